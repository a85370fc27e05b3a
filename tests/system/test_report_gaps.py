"""swarm report on runs whose recording has gaps, is cut, or is a real-time
swarm's: exit 0, report.md and the four figures. An error of its own exits
1 with one line and its traceback in a log; 2 is for usage errors only.

Telemetry gaps are made two ways: by freeze faults in lockstep (a frozen
agent answers no observation, so its telemetry misses exactly the frozen
ticks), and, for the fast tests, by a recording written here with the rows
of those ticks left out.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from formation_swarm.launch.launcher import RunResult
from formation_swarm.report import figures
from formation_swarm.report.build import FIGURES, TRACEBACK_LOG, main
from formation_swarm.report.data import read_recording

DT_S = 0.05
TICKS = 200
WINDOW_TICKS = 20  # the V_N moving average's 1 s: a stretch shorter than this broke it


def reported(run_dir: Path) -> None:
    """``swarm report RUN_DIR`` exits 0 with report.md and the four figures."""
    assert main([str(run_dir)]) == 0
    out = run_dir / "report"
    assert (out / "report.md").is_file()
    drawn = sorted(p.name for p in out.glob("*.png"))
    assert drawn == sorted(f"{stem}.png" for stem in FIGURES)
    assert all((out / name).stat().st_size > 10_000 for name in drawn)
    assert not (out / TRACEBACK_LOG).exists()


def telemetry_gaps(res: RunResult, robot: int) -> list[list[int]]:
    """The runs of ticks the logger missed of ``robot``'s telemetry, [first, last]."""
    return res.summary["parts"]["logger"]["ticks"][str(robot)]["gaps"]


# -- gaps made by freezes (lockstep), a cut recording, a real-time swarm -------------


FREEZES = {
    # two gaps of the length, one tick apart: a stretch of one tick between them
    1: (["freeze agent-2@5s for=0.05s", "freeze agent-2@5.1s for=0.05s"], [[100, 100], [102, 102]]),
    2: (["freeze agent-2@5s for=0.1s", "freeze agent-2@5.15s for=0.1s"], [[100, 101], [103, 104]]),
    # 11 ticks between: shorter than the moving average's window
    19: (["freeze agent-2@5s for=0.95s", "freeze agent-2@6.5s for=0.95s"], [[100, 118], [130, 148]]),
}


@pytest.mark.slow
@pytest.mark.parametrize("gap_ticks", sorted(FREEZES))
def test_telemetry_gaps_from_freezes(swarm_run: Callable[..., RunResult], gap_ticks: int) -> None:
    faults, gaps = FREEZES[gap_ticks]
    res = swarm_run("fig7_turn_vn_dynamic", overrides={"run.duration_s": 10.0}, faults=faults)
    assert res.exit_code == 0
    assert telemetry_gaps(res, 2) == gaps
    assert all(b - a + 1 == gap_ticks for a, b in gaps)
    assert gaps[1][0] - gaps[0][1] - 1 < WINDOW_TICKS
    reported(res.run_dir)


@pytest.mark.slow
def test_a_recording_cut_by_killing_the_logger(swarm_run: Callable[..., RunResult]) -> None:
    # In real time: the logger flushes every 0.5 s of wall time, so 6 s hold most of 6 s of the
    # run (lockstep passes those 6 s faster than the logger's first flush).
    overrides = {"run.duration_s": 12.0}
    res = swarm_run("fig11_obstacles", mode="realtime", overrides=overrides, faults=["kill logger@6s"])
    assert res.summary["ticks"] == 240
    assert [e["process"] for e in res.summary["events"] if e["event"] == "killed"] == ["logger"]
    reported(res.run_dir)
    md = (res.run_dir / "report" / "report.md").read_text()
    assert "**The recording is cut short:**" in md
    last_s = read_recording(res.run_dir / "recording.rrd")["/robots/r1/pose"].t[-1]
    assert 1.0 < last_s <= 6.0  # the recording ends at the kill (its tick's truth may be in), not at 12 s


@pytest.mark.slow
def test_a_real_time_run_of_100_robots(swarm_run: Callable[..., RunResult]) -> None:
    # Ten robots' agents to a process: the report reads the same recording, and ten
    # processes take a third less CPU to start and run than a hundred.
    overrides = {"run.robots": 100, "leader.formation": "line", "run.duration_s": 10.0, "run.agents_per_process": 10}
    res = swarm_run("fig11_obstacles", mode="realtime", overrides=overrides, timeout_s=600)
    assert res.exit_code == 0
    assert res.summary["mode"] == "realtime"
    assert len(res.summary["followers"]) == 99
    reported(res.run_dir)


# -- gaps made by leaving rows out of a recording written here ------------------------


def synthetic_run(folder: Path, missing: list[int]) -> Path:
    """A run folder of a leader (R1) and a follower (R2) over TICKS ticks:
    summary.json and a recording of what swarm report reads, without R2's
    telemetry (V_N, readings, EKF) at the ``missing`` ticks."""
    import rerun as rr

    folder.mkdir()
    run_id = f"synthetic-{folder.name}"
    ticks = np.arange(TICKS)
    t = ticks * DT_S
    kept = ~np.isin(ticks, missing)
    rec = rr.RecordingStream("formation-swarm", recording_id=run_id)
    rec.save(str(folder / "recording.rrd"))

    def column(entity: str, times: np.ndarray, values: np.ndarray) -> None:
        cols = rr.Points2D.columns(positions=values) if values.ndim == 2 else rr.Scalars.columns(scalars=values)
        rec.send_columns(entity, indexes=[rr.TimeColumn("sim_time", duration=times)], columns=cols)

    leader = np.c_[1.5 * t, np.sin(t)]
    follower = leader - [1.5, 1.5]
    target = follower + 0.1 * np.c_[np.cos(3 * t), np.sin(3 * t)]
    column("robots/r1/pose", t, leader)
    column("robots/r2/pose", t, follower)
    column("robots/r2/target/true", t, target)
    column("robots/r2/error/formation", t, np.hypot(*(target - follower).T))
    column("robots/r2/fis/v_n", t[kept], 1.5 + 0.5 * (ticks[kept] % 2))
    column("robots/r2/target/measured", t[kept], target[kept] + 0.05)
    column("robots/r2/ekf/target", t[kept], target[kept] + 0.02)
    column("robots/r2/error/measured", t[kept], np.full(kept.sum(), 0.07))
    column("robots/r2/error/ekf", t[kept], np.full(kept.sum(), 0.03))
    rec.flush(timeout_sec=5.0)
    rec.disconnect()
    summary = {
        "run_id": run_id,
        "scenario": "synthetic",
        "seed": 1,
        "mode": "lockstep",
        "ticks": TICKS,
        "exit_code": 0,
        "recording": "recording.rrd",
        "followers": {"2": {"rms_m": 0.1}},
    }
    (folder / "summary.json").write_text(json.dumps(summary))
    return folder


@pytest.mark.parametrize("gap_ticks", [1, 2, 19])
def test_telemetry_gaps_from_rows_left_out(tmp_path: Path, gap_ticks: int) -> None:
    """Two gaps of ``gap_ticks`` with one tick between them, and a lone tick
    at the start and at the end of the run."""
    second = 100 + gap_ticks + 1
    missing = [*range(100, 100 + gap_ticks), *range(second, second + gap_ticks), 1, TICKS - 2]
    reported(synthetic_run(tmp_path / "run", missing))


def test_an_error_of_its_own_exits_1_with_one_line_and_a_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    run = synthetic_run(tmp_path / "run", [])

    def broken(*_args: object, **_kwargs: object) -> None:
        raise ValueError("shapes (20,) and (1,)\ndo not match")  # a ValueError: once taken for a usage error

    monkeypatch.setattr(figures, "vn", broken)
    assert main([str(run)]) == 1
    out, err = capsys.readouterr()
    log = run / "report" / TRACEBACK_LOG
    assert out == ""
    *progress, said = err.splitlines()  # the progress on stderr, then the one line of the error
    assert progress == [f"report: figure {k}/4 {stem}.png" for k, stem in enumerate(FIGURES[:3], start=1)]
    assert said.startswith("swarm report: drawing vn.png: ValueError: ")  # the figure, the error's type
    assert said.endswith(f"(traceback in {log})")
    assert "shapes (20,) and (1,) do not match" in said  # its two lines in one
    text = log.read_text()
    assert text.startswith("Traceback (most recent call last):")
    assert "in broken" in text
    assert "drawing vn.png" in text
    # Mended, the next report leaves no log of the failure behind.
    monkeypatch.undo()
    reported(run)


def test_a_report_it_cannot_write_exits_1_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = synthetic_run(tmp_path / "run", [])
    (run / "report").write_text("a file where the report's folder goes")
    assert main([str(run)]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1
    assert err.startswith(f"swarm report: cannot write the report into {run}: NotADirectoryError: ")
    log = Path(err.rstrip().rpartition("(traceback in ")[2].removesuffix(")"))
    assert log.parent != run  # the run folder cannot take it: the system's temporary folder does
    assert "Traceback" in log.read_text()
    log.unlink()


def test_usage_errors_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(tmp_path / "missing")]) == 2
    (said,) = capsys.readouterr().err.splitlines()
    assert said.startswith(f"swarm report: {tmp_path / 'missing'}: ")
    assert said.endswith("no such folder")
    run = synthetic_run(tmp_path / "run", [])
    (run / "summary.json").write_text("[]")
    assert main([str(run)]) == 2
    assert "is not a run summary" in capsys.readouterr().err
    with pytest.raises(SystemExit) as bad:
        main([str(run), "--dpi", "7"])
    assert bad.value.code == 2
