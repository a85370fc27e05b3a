"""swarm sweep with real runs: tables written and resumed, a lossy run run again, Ctrl-C."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from formation_swarm.runtime import summary as summary_mod
from formation_swarm.studies.jobs import Job
from formation_swarm.studies.sweep import Sweep
from tests.helpers import SCENARIOS


def test_sweep_writes_tables_and_resumes(tmp_path: Path) -> None:
    jobs = [Job("controller.vn=1.5", {"controller.vn": 1.5, "run.duration_s": 5.0}, s) for s in (0, 1)]
    lines: list[str] = []
    sweep = Sweep(SCENARIOS / "fig7_turn_vn_dynamic.toml", jobs, tmp_path, workers=2, progress=lines.append)
    rows = sweep.run()
    jobs = sweep.jobs  # named after the scenario as run, too
    assert [r["seed"] for r in rows] == [0, 1]
    assert all(r["exit_code"] == 0 and r["ticks"] == 100 for r in rows)
    assert sum("2/2" in line for line in lines) == 1  # progress, one line per finished run
    with (tmp_path / "runs.csv").open() as f:
        table = list(csv.DictReader(f))
    assert [int(r["seed"]) for r in table] == [0, 1]
    assert float(table[0]["r2_rms_m"]) > 0
    with (tmp_path / "aggregate.csv").open() as f:
        agg = {r["metric"]: r for r in csv.DictReader(f)}
    assert int(agg["r2_rms_m"]["n"]) == 2
    assert (tmp_path / "aggregate.png").stat().st_size > 10_000  # the figure of aggregate.csv
    # A lost or failed run is run again; finished ones are not.
    first = json.loads((tmp_path / "runs" / jobs[0].name / "summary.json").read_text())
    (tmp_path / "runs" / jobs[1].name / "summary.json").unlink()
    lines.clear()
    again = Sweep(SCENARIOS / "fig7_turn_vn_dynamic.toml", jobs, tmp_path, workers=2, progress=lines.append).run()
    assert "1/2 runs already done" in lines[0]
    assert len(again) == 2
    assert json.loads((tmp_path / "runs" / jobs[0].name / "summary.json").read_text()) == first
    assert again[1]["r2_rms_m"] == rows[1]["r2_rms_m"]  # lockstep: the rerun is the same run
    # The same combination with a fault (or a changed scenario) is another run, never a finished one reused.
    lines.clear()
    blind = Sweep(
        SCENARIOS / "fig7_turn_vn_dynamic.toml",
        jobs[:1],
        tmp_path,
        workers=1,
        progress=lines.append,
        faults=["blackout 2@1s"],
    ).run()
    assert not any("already done" in line for line in lines)
    assert blind[0]["run"] != jobs[0].name
    assert blind[0]["r2_rms_m"] != rows[0]["r2_rms_m"]


def test_a_run_that_lost_ticks_is_run_again_and_the_lossy_attempt_kept(tmp_path: Path, monkeypatch) -> None:
    """The first attempt's recording misses ticks (its logger's count cut to 25
    of 40, as two test suites saw happen): the sweep says so, keeps that attempt
    beside the run and runs it again."""
    from formation_swarm.launch.launcher import Launch

    real_wait, results = Launch.wait, []

    def first_lossy(self: Launch, *args: object, **kwargs: object) -> object:
        res = real_wait(self, *args, **kwargs)
        if not results:
            res.summary["parts"]["logger"]["messages"]["truth"] = 25
        results.append(res)
        return res

    monkeypatch.setattr(Launch, "wait", first_lossy)
    lines: list[str] = []
    job = Job("controller.vn=1.5", {"controller.vn": 1.5, "run.duration_s": 2.0}, 0)
    sweep = Sweep(SCENARIOS / "fig7_turn_vn_dynamic.toml", [job], tmp_path, logger=True, progress=lines.append)
    rows = sweep.run()
    assert [r["exit_code"] for r in rows] == [0]
    name = rows[0]["run"]
    assert [r.summary["ticks"] for r in results] == [40, 40]  # two whole runs of 2 s at 20 Hz
    kept = tmp_path / "runs" / f"{name}.incomplete"
    assert json.loads((kept / "summary.json").read_text())["ticks"] == 40
    assert summary_mod.recording_gap(json.loads((tmp_path / "runs" / name / "summary.json").read_text())) is None
    again = [line for line in lines if "running it again" in line]
    assert again == [
        f"[sweep] {name}: the logger recorded 25 of the 40 ticks the world sent; running it again "
        f"(its metrics would miss those ticks; this attempt is kept in {kept})"
    ]


def test_ctrl_c_stops_the_run_in_flight_and_marks_it_interrupted(tmp_path: Path) -> None:
    """The pool waited for its runs before the handler could stop them: the run
    in flight went on to its end (leader_finished) while the console said it
    was being stopped."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from tests.helpers import our_processes

    out = tmp_path / "sw"
    cmd = [
        sys.executable,
        "-m",
        "formation_swarm.cli",
        "sweep",
        "fig11_obstacles",
        "--seeds",
        "2",
        "--jobs",
        "1",
        "--set",
        "run.robots=20",
        "--set",
        "leader.formation=line",
        "--out",
        str(out),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not list(out.glob("runs/*/stats/agent-2.json")):
        time.sleep(0.05)  # the first run is flying: an agent wrote its stats (once a second)
    assert list(out.glob("runs/*/stats/agent-2.json")), "the first run never started"
    os.killpg(proc.pid, signal.SIGINT)  # a terminal's Ctrl-C
    said, _ = proc.communicate(timeout=60)
    assert proc.returncode == 130, said
    assert "[sweep] interrupted: stopping the runs in flight (finished runs are kept)" in said
    assert "Traceback" not in said
    (run,) = [p.parent for p in out.glob("runs/*/summary.json")]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["end_reason"] == "interrupted", summary["ended"]
    assert summary["exit_code"] == 130
    assert summary["ticks"] < 1061  # it did not fly to its end
    assert not (out / "runs.csv").exists()  # nothing finished: no empty tables; the run is run again on resume
    assert not (out / "aggregate.csv").exists()
    assert [c for _, c in our_processes() if str(out) in c] == []
