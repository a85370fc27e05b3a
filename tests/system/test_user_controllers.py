"""A user's follower controller in real runs (docs/controllers.md).

A law that cannot be flown is refused by ``swarm run`` before anything
starts: one line, exit 2, no run folder. A controller that raises at tick
100, or returns NaN there, stops its robot only: the run goes on, says
which controller failed at which tick (console, summary.json, the agent's
log with the traceback) and exits 1. Its own telemetry values are in the
recording under the robot. The example package's controller
(examples/pure_pursuit) flies fig11_obstacles from the command line, two
lockstep runs giving one digest, and a sweep over its parameters.

The agents import the test controllers (tests.helpers.controllers) from
the launcher's Python path: the repository's root, which pytest puts on it
in this process (the fork server copies it) and PYTHONPATH gives the
``swarm`` commands run here.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

from formation_swarm.launch.console import print_result
from formation_swarm.launch.launcher import RunResult
from formation_swarm.runtime.summary.end_reason import describe_controller_failures
from tests.helpers import ROOT, rrd_rows
from tests.helpers.controllers import LAW

SWARM = Path(sys.executable).parent / "swarm"
COMMAND = [str(SWARM)] if SWARM.exists() else [sys.executable, "-m", "formation_swarm.cli"]
EXAMPLE = ROOT / "examples" / "pure_pursuit"
PURE_PURSUIT = "pure_pursuit_controller:PurePursuit"
PAPER = f"{LAW}:Paper"


def swarm(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """A ``swarm`` command with the test controllers and the example on its Python path."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(EXAMPLE)])}
    return subprocess.run([*COMMAND, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


# -- refused before anything starts --------------------------------------------------

REFUSED = {
    "a missing module": (
        ["--set", "controller.law=no_such_module_xyz:Follower"],
        "controller.law: cannot import 'no_such_module_xyz' for law 'no_such_module_xyz:Follower': "
        "no module named 'no_such_module_xyz'; is it installed or on PYTHONPATH?",
    ),
    "a missing class": (
        ["--set", f"controller.law={LAW}:Papr"],
        f"controller.law: module '{LAW}' has no class 'Papr'; did you mean 'Paper'?",
    ),
    "a class without step": (
        ["--set", f"controller.law={LAW}:NoStep"],
        f"controller.law: class NoStep of law '{LAW}:NoStep' has no step method: a follower controller needs "
        "step(FollowerInput) -> FollowerOutput (docs/controllers.md)",
    ),
    "an unknown parameter": (
        ["--set", f"controller.law={PAPER}", "--set", "controller.params.fail_at_stp=3"],
        "unknown key controller.params.fail_at_stp; did you mean 'fail_at_step'?",
    ),
}


@pytest.fixture(scope="module")
def refused(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, subprocess.CompletedProcess[str]]]:
    def one(case: str) -> tuple[Path, subprocess.CompletedProcess[str]]:
        folder = tmp_path_factory.mktemp("refused")
        return folder, swarm(["run", "fig11_obstacles", *REFUSED[case][0]], folder)

    with ThreadPoolExecutor(max_workers=4) as pool:
        return dict(zip(REFUSED, pool.map(one, REFUSED), strict=True))


@pytest.mark.parametrize("case", list(REFUSED))
def test_a_law_that_cannot_be_flown_is_one_line_exit_2_and_no_run_folder(
    refused: dict[str, tuple[Path, subprocess.CompletedProcess[str]]], case: str
) -> None:
    folder, proc = refused[case]
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith("swarm run: ")
    assert REFUSED[case][1] in proc.stderr
    assert list(folder.iterdir()) == []  # no runs/, no run folder


# -- a controller that fails mid-run ---------------------------------------------------


def _failing_run(swarm_run: Callable[..., RunResult], rid: int, param: str, *, logger: bool) -> RunResult:
    """fig11 for 12 s, follower ``rid`` flying the test controller with ``param``
    = 100 (its 101st step: tick 100 in lockstep), the other the paper's."""
    overrides = {f"followers.{rid}.law": PAPER, f"followers.{rid}.params.{param}": 100, "run.duration_s": 12.0}
    return swarm_run("fig11_obstacles", overrides=overrides, logger=logger)


def test_a_controller_that_raises_at_tick_100_stops_its_robot_and_the_run_fails(
    swarm_run: Callable[..., RunResult],
) -> None:
    res = _failing_run(swarm_run, 3, "fail_at_step", logger=True)
    s = res.summary
    error = "RuntimeError: failing on purpose at step 100"
    assert res.exit_code == 1
    assert s["exit_code"] == 1
    assert s["end_reason"] == "duration_reached"  # the run went on to its end
    assert s["controller_failures"] == [{"robot": 3, "tick": 100, "error": error, "law": PAPER}]
    assert s["failure"] == describe_controller_failures(s["controller_failures"])  # that, and nothing else
    out = io.StringIO()
    print_result(res, out)
    assert (
        f"  failed: a controller failed, its robot stopped: robot 3's controller ({PAPER}) at tick 100: {error}\n"
        in out.getvalue()
    )
    log = (res.run_dir / "logs" / "agent-3.log").read_text()
    assert f"controller {PAPER} failed at tick 100: {error}" in log
    assert "Traceback (most recent call last)" in log
    assert 'raise RuntimeError(f"failing on purpose at step {step}")' in log
    # Robot 2 flew on; robot 3 stood still from tick 100 while its slot moved on (1.5 m/s for 7 s).
    f2, f3 = s["followers"]["2"], s["followers"]["3"]
    assert f2["rms_m"] < 1.0
    assert f3["max_m"] > 8.0
    assert s["ticks"] == 240
    assert s["lockstep_misses"] == 0
    # Its own values (steps, scale) are in the recording for the 100 ticks it flew.
    rows = rrd_rows(res.recording)
    assert rows.get("/robots/r3/controller/steps") == 100
    assert rows.get("/robots/r3/controller/scale") == 100
    assert not any(path.startswith("/robots/r2/controller/") for path in rows)  # the paper's: none


def test_a_controller_that_returns_nan_at_tick_100_stops_its_robot_and_the_run_fails(
    swarm_run: Callable[..., RunResult],
) -> None:
    res = _failing_run(swarm_run, 2, "nan_at_step", logger=False)
    s = res.summary
    assert res.exit_code == 1
    [failure] = s["controller_failures"]
    assert (failure["robot"], failure["tick"], failure["law"]) == (2, 100, PAPER)
    assert failure["error"].startswith("ValueError: wheel speeds must be finite numbers, got left_mps=nan, right_mps=")
    assert s["end_reason"] == "duration_reached"
    assert s["followers"]["2"]["max_m"] > 8.0
    assert s["rejected_total"] == 0  # nothing NaN reached the wire
    assert "Traceback (most recent call last)" in (res.run_dir / "logs" / "agent-2.log").read_text()


# -- the example package from the command line ---------------------------------------


def test_swarm_run_flies_the_example_controller_and_two_lockstep_runs_give_one_digest(tmp_path: Path) -> None:
    summaries = []
    for i in range(2):
        proc = swarm(
            ["run", "fig11_obstacles", "--no-logger", "--set", f"controller.law={PURE_PURSUIT}", "--out", f"r{i}"],
            tmp_path,
        )
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "follower R3: formation error RMS" in proc.stdout
        (header,) = [line for line in proc.stdout.splitlines() if line.startswith("[swarm] run ")]
        assert f", leader path, law {PURE_PURSUIT}, folder " in header  # what flew, before it flies
        summaries.append(json.loads((tmp_path / f"r{i}" / "summary.json").read_text()))
    a, b = summaries
    assert a["trajectory_digest"] is not None
    assert a["trajectory_digest"] == b["trajectory_digest"]
    assert a["followers"] == b["followers"]
    # Measured: R2 0.27 m, R3 0.79 m RMS (its two formation changes included).
    assert a["followers"]["2"]["rms_m"] < 0.8
    assert a["followers"]["3"]["rms_m"] < 2.4
    assert (a["collisions"], a["controller_failures"]) == (0, [])


def test_a_sweep_over_the_controllers_parameters(tmp_path: Path) -> None:
    args = ["sweep", "fig11_obstacles", "--seeds", "1", "--out", "sw", "--set", f"controller.law={PURE_PURSUIT}"]
    args += ["--set", "controller.params.gain=1,3", "--set", "run.duration_s=15"]
    proc = swarm(args, tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = list(csv.DictReader((tmp_path / "sw" / "runs.csv").open()))
    assert [r["combination"].split()[1] for r in rows] == ["controller.params.gain=1", "controller.params.gain=3"]
    assert {r["exit_code"] for r in rows} == {"0"}
    slow, quick = (float(r["r2_rms_m"]) for r in rows)
    assert quick < slow  # a stiffer gain keeps it nearer its slot (measured: 0.11 vs 0.19 m over 15 s)


# -- one's own law beside the paper's ---------------------------------------------------------


def test_compare_and_the_report_name_ones_law_and_the_papers(
    swarm_run: Callable[..., RunResult], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """fig11 for 3 s as shipped, then with docs/controllers.md's Proportional:
    compare's legend names both laws and lists controller.law as differing;
    the report's text and every figure's title name the law flown."""
    import matplotlib

    matplotlib.use("Agg")
    from formation_swarm.report.build import FIGURES, make_report
    from formation_swarm.report.compare import differing, figure
    from formation_swarm.report.data import load_run
    from formation_swarm.report.figures import drawing

    doc = (ROOT / "docs" / "controllers.md").read_text()
    (tmp_path / "law").mkdir()
    (tmp_path / "law" / "doc_proportional.py").write_text(re.findall(r"^```python\n(.*?)^```$", doc, re.M | re.S)[0])
    mine = "doc_proportional:Proportional"
    paper = swarm_run("fig11_obstacles", overrides={"run.duration_s": 3.0})
    # On the launcher's path, which each agent it forks takes (the fork server, started before, keeps its own).
    monkeypatch.syspath_prepend(str(tmp_path / "law"))
    own = swarm_run("fig11_obstacles", overrides={"run.duration_s": 3.0, "controller.law": mine})
    assert (paper.exit_code, own.exit_code) == (0, 0)
    assert [paper.summary["laws"], own.summary["laws"]] == [
        {"leader": "path", "followers": {"2": "fuzzy (V_N dynamic)", "3": "fuzzy (V_N dynamic)"}},
        {"leader": "path", "followers": {"2": mine, "3": mine}},
    ]
    runs = [load_run(paper.run_dir), load_run(own.run_dir)]
    fig = figure(runs)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels[0].endswith(", leader path, law fuzzy (V_N dynamic)")  # the paper's, with its V_N
    assert labels[1].endswith(f", leader path, law {mine}")
    assert "controller.law" in differing(runs)
    saved: list[Any] = []

    def save(fig: Any, path: Path, dpi: int) -> None:  # no drawing: the report still moves each file into place
        saved.append(fig)
        Path(path).write_bytes(b"")

    monkeypatch.setattr(drawing, "save", save)
    out = make_report(own.run_dir)
    titles = [f._suptitle.get_text() for f in saved]
    assert len(titles) == 4
    assert all(f"leader path, law {mine}" in title.splitlines() for title in titles)
    vn_note = [t.get_text() for t in saved[FIGURES.index("vn")].axes[0].texts]
    assert any(mine in note and "no V_N" in note for note in vn_note)  # it sent no V_N: said by its name
    assert f"Control: leader path, law {mine}." in (out / "report.md").read_text().splitlines()
