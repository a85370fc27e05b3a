"""load_run, swarm export and swarm compare on two short lockstep runs with their logger."""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from formation_swarm import load_run
from formation_swarm.launch.launcher import Launch
from formation_swarm.report.data import RunData
from tests.helpers import ROOT, SCENARIOS


def _run(out: Path, scenario: str, seed: int) -> Path:
    with Launch(
        SCENARIOS / scenario, seed=seed, out=out, overrides={"run.duration_s": 2.0}, progress=lambda _line: None
    ) as launch:
        res = launch.wait(timeout_s=120.0)
    assert res.exit_code == 0
    return res.run_dir


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """fig11 (a leader, two followers) and fig7 (a leader, one follower), 2 s (40 ticks) each."""
    base = tmp_path_factory.mktemp("data")
    return _run(base / "fig11-s3", "fig11_obstacles.toml", 3), _run(base / "fig7-s5", "fig7_turn_vn_dynamic.toml", 5)


def _rms(x: np.ndarray) -> float:
    return math.sqrt(float(np.mean(np.square(x))))


def test_load_run_holds_every_tick_and_the_summarys_numbers(runs: tuple[Path, Path]) -> None:
    run = load_run(runs[0])
    s = run.summary
    assert isinstance(run, RunData)
    assert (run.robots, run.followers, run.scenario, run.seed, run.dt_s) == ((1, 2, 3), (2, 3), s["scenario"], 3, 0.05)
    assert run.tick.tolist() == list(range(s["ticks"])) == list(range(40))
    assert np.allclose(run.time_s, run.tick * 0.05, rtol=0, atol=1e-9)
    assert run.pose.shape == (3, 40, 3)
    assert run.target_true.shape == run.target_ekf.shape == run.wheels_mps.shape == (3, 40, 2)
    leader = run.index(1)
    assert np.all(np.isnan(run.formation_error_m[leader]))
    assert np.all(run.formation[leader] == -1)
    assert np.all(run.formation[[run.index(2), run.index(3)]] == 0)  # the triangle throughout
    assert run.pose[leader, 0].tolist() == pytest.approx([0.0, 0.0, math.pi / 2], abs=1e-6)  # the path heads +y
    errors = s["parts"]["logger"]["target_errors"]
    for rid in run.followers:
        i = run.index(rid)
        assert not np.any(np.isnan(run.formation_error_m[i]))
        assert _rms(run.formation_error_m[i]) == pytest.approx(s["followers"][str(rid)]["rms_m"], abs=1e-9)
        assert float(np.max(run.formation_error_m[i])) == pytest.approx(s["followers"][str(rid)]["max_m"], abs=1e-9)
        assert _rms(run.ekf_error_m[i]) == pytest.approx(errors[str(rid)]["ekf_rms_m"], abs=1e-9)
        assert _rms(run.measured_error_m[i]) == pytest.approx(errors[str(rid)]["measured_rms_m"], abs=1e-9)
        # The error is the distance between the recorded points (float32 in the recording).
        recomputed = np.hypot(*(run.target_true[i] - run.pose[i, :, :2]).T)
        assert np.max(np.abs(recomputed - run.formation_error_m[i])) < 1e-5
        assert np.max(np.abs(np.hypot(*(run.target_ekf[i] - run.target_true[i]).T) - run.ekf_error_m[i])) < 1e-5
        assert np.all(run.v_n_mps[i] > 0)
        assert np.all(np.isfinite(run.wheels_mps[i]))
    with pytest.raises(ValueError, match="robot must be one of"):
        run.index(9)


def test_export_writes_one_row_per_robot_per_tick(
    runs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import pyarrow.parquet as pq

    from formation_swarm.report.export import main

    run = load_run(runs[0])
    assert main([str(runs[0])]) == 0
    with (runs[0] / "run.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(run.robots) * len(run.tick) == 3 * 40
    assert [(int(r["robot"]), int(r["tick"])) for r in rows[:2]] == [(1, 0), (1, 1)]
    for rid in run.followers:
        err = np.array([float(r["formation_error_m"]) for r in rows if r["robot"] == str(rid)])
        assert len(err) == 40
        assert _rms(err) == pytest.approx(run.summary["followers"][str(rid)]["rms_m"], abs=1e-9)
    leader_rows = [r for r in rows if r["robot"] == "1"]
    assert all(r["formation_error_m"] == "" and r["formation"] == "" for r in leader_rows)
    capsys.readouterr()
    assert main([str(runs[0])]) == 0  # the run's own file: made again over the one there, said so
    said = capsys.readouterr().out
    assert said.startswith(f"[export] {run.run_dir / 'run.csv'} ")
    assert said.endswith(" (made again over the one there)\n")
    assert main([str(runs[0]), "--out", str(runs[0] / "run.csv")]) == 2  # named by --out: refused without --force
    assert main([str(runs[0]), "--format", "parquet", "--out", str(tmp_path / "t.parquet")]) == 0
    table = pq.read_table(tmp_path / "t.parquet")
    assert table.num_rows == 120
    assert table.column("formation_error_m").null_count == 40  # the leader's
    from_csv = [float(r["y_m"]) for r in rows]
    assert table.column("y_m").to_pylist() == from_csv  # CSV keeps full precision


def test_clear_errors_for_folders_it_cannot_use(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from formation_swarm.report.compare import main as compare
    from formation_swarm.report.export import main as export

    assert export([str(tmp_path / "nowhere")]) == 2
    assert "no such folder" in capsys.readouterr().err
    (tmp_path / "summary.json").write_text("{}")
    assert export([str(tmp_path)]) == 2
    assert "summary.json is not a run summary (a JSON object with the run's run_id)" in capsys.readouterr().err
    (tmp_path / "summary.json").write_text('{"run_id": "r1"}')
    assert export([str(tmp_path)]) == 2
    assert "no recording.rrd" in capsys.readouterr().err
    assert compare([str(tmp_path / "nowhere"), "--out", str(tmp_path / "c.png")]) == 2
    assert "nowhere: no such folder" in capsys.readouterr().err
    assert not (tmp_path / "c.png").exists()


def test_compare_draws_a_line_per_robot_per_run(runs: tuple[Path, Path], tmp_path: Path) -> None:
    from formation_swarm.report.compare import figure, label, main

    a, b = load_run(runs[0]), load_run(runs[1])
    fig = figure([a, b])
    traj, err = fig.axes[:2]
    assert len(traj.lines) == 3 + 2  # every robot of each run
    assert len(err.lines) == 2 + 1  # every follower of each run
    assert err.lines[2].get_ydata().tolist() == b.formation_error_m[b.index(2)].tolist()
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == [label(a), label(b)]  # two scenarios: no key differs
    assert [text.split(", ")[:2] for text in labels] == [
        ["fig11-s3: fig11-obstacles", "seed 3"],
        ["fig7-s5: turn-vn-dynamic", "seed 5"],
    ]
    assert [run.summary["laws"] for run in (a, b)] == [
        {"leader": "path", "followers": {"2": "fuzzy (V_N dynamic)", "3": "fuzzy (V_N dynamic)"}},
        {"leader": "path", "followers": {"2": "fuzzy (V_N dynamic)"}},
    ]
    assert all(text.endswith(", leader path, law fuzzy (V_N dynamic)") for text in labels)
    assert main([str(runs[0]), str(runs[1]), "--out", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").stat().st_size > 10_000


def test_compare_names_what_differs_between_runs_of_one_scenario() -> None:
    from types import SimpleNamespace

    from formation_swarm.report.compare import differing, label

    def run(name: str, speed: float, seed: int, **more: object) -> SimpleNamespace:
        config = {"run": {"name": "fig11-obstacles", "seed": seed}, "leader": {"speed_mps": speed, **more}}
        return SimpleNamespace(
            config=config, scenario="fig11-obstacles", seed=seed, run_dir=Path(name), summary={}, followers=(2, 3)
        )

    a, b = run("a", 1.5, 1), run("b", 2.0, 2, formation="line")
    assert differing([a, b]) == ["leader.formation", "leader.speed_mps"]  # the seed is in the label already
    assert label(b, differing([a, b])).endswith(", leader.formation=line, leader.speed_mps=2.0")  # type: ignore[arg-type]
    assert label(a, differing([a, b])).endswith(", leader.formation: default, leader.speed_mps=1.5")  # type: ignore[arg-type]
    faulted = SimpleNamespace(**{**vars(a), "config": {**a.config, "faults": [{"kind": "kill"}, {"kind": "drop"}]}})
    assert differing([a, faulted]) == ["faults"]
    assert label(faulted, ["faults"]).endswith(", faults: 2 entries")  # type: ignore[arg-type]  # not the schedule
    assert label(a, ["faults"]).endswith(", faults: none")  # type: ignore[arg-type]
    other = SimpleNamespace(**{**vars(b), "scenario": "turn-vn-dynamic"})
    assert differing([a, other]) == []  # different scenarios: their names tell them apart
    # A law that differs is a key that differs; the label says the laws themselves, not the keys.
    own = SimpleNamespace(
        **{**vars(a), "config": {**a.config, "controller": {"vn": 1.5}, "followers": {"3": {"law": "lpsi"}}}}
    )
    assert differing([a, own]) == ["controller.vn", "followers.3.law"]
    assert label(own, differing([a, own])).endswith(", laws R2 fuzzy (V_N 1.5 m/s); R3 lpsi")  # type: ignore[arg-type]


def test_the_documented_example_runs(runs: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    doc = (ROOT / "docs" / "data.md").read_text()
    (code,) = re.findall(r"```python\n(.*?)```", doc, flags=re.S)
    assert '"runs/fig7"' in code
    monkeypatch.chdir(tmp_path)
    scope: dict[str, object] = {}
    exec(compile(code.replace('"runs/fig7"', repr(str(runs[0]))), "docs/data.md", "exec"), scope)  # noqa: S102
    try:
        ax, run = scope["ax"], load_run(runs[0])
        assert [line.get_label() for line in ax.lines] == ["R2", "R3"]
        assert ax.lines[1].get_ydata().tolist() == run.formation_error_m[run.index(3)].tolist()
        assert (tmp_path / "formation_error.png").stat().st_size > 10_000
    finally:
        plt.close("all")


def test_a_recording_from_another_run_is_refused(runs: tuple[Path, Path], tmp_path: Path) -> None:
    import shutil

    mixed = tmp_path / "mixed"
    shutil.copytree(runs[0], mixed)
    shutil.copy(runs[1] / "recording.rrd", mixed / "recording.rrd")
    other = json.loads((runs[1] / "summary.json").read_text())["run_id"]
    mine = json.loads((runs[0] / "summary.json").read_text())["run_id"]
    with pytest.raises(ValueError, match=f"is the recording of run {other}, not of {mine} \\(summary.json\\)"):
        load_run(mixed)
