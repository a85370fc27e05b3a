"""swarm report, compare and export on real run folders: a run stopped by
Ctrl-C (before its first tick, and while it ran), whose report points only
to what the folder holds and whose figures say they were interrupted; the
progress lines; a user's controller's own values in the exported table."""

from __future__ import annotations

import csv
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from formation_swarm.launch.launcher import RunResult
from formation_swarm.report.build import make_report
from formation_swarm.report.figures import FIGURES, drawing
from tests.helpers.controllers import LAW

pytestmark = pytest.mark.slow

SWARM = Path(sys.executable).parent / "swarm"
COMMAND = [str(SWARM)] if SWARM.exists() else [sys.executable, "-m", "formation_swarm.cli"]
DEADLINE_S = 120.0


def swarm(argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*COMMAND, *argv], cwd=cwd, capture_output=True, text=True, timeout=DEADLINE_S, check=False)


def interrupted_run(out: Path, after: str) -> Path:
    """``swarm run`` in real time, Ctrl-C'd (SIGINT to its process group) once
    a line of its console matches ``after``; its run folder."""
    proc = subprocess.Popen(
        [*COMMAND, "run", "fig11_obstacles", "--mode", "realtime", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + DEADLINE_S
        assert proc.stdout is not None
        for line in proc.stdout:  # each line as it comes; the run's own deadline ends the loop
            if re.search(after, line) or time.monotonic() > deadline:
                break
        os.killpg(proc.pid, signal.SIGINT)
        proc.communicate(timeout=DEADLINE_S)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
    assert proc.returncode == 130
    return out


def pointers_hold(said: str, run: Path) -> None:
    """Every place the report's words send the reader to is there."""
    if "see its logs/" in said:
        assert (run / "logs").is_dir()
    if "it has no logs/" in said:
        assert not (run / "logs").exists()
    if "logs/logger.log" in said:
        assert (run / "logs" / "logger.log").is_file()
    if held := re.search(r"the folder holds ([^)]*)\)", said):
        assert held.group(1).split(", ") == sorted(
            p.name + ("/" if p.is_dir() else "") for p in run.iterdir() if p.name != "report"
        )


def test_a_run_interrupted_at_its_start_points_to_what_is_there(tmp_path: Path) -> None:
    run = interrupted_run(tmp_path / "run", after=r"^\[swarm\] run ")
    proc = swarm(["report", str(run)], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "nothing was recorded: the run was interrupted before its first tick (exit code 130); " in proc.stdout
    assert re.search(r"; (see its logs/|it has no logs/ \(the folder holds [^)]*\))$", proc.stdout.strip())
    pointers_hold(proc.stdout, run)
    pointers_hold((run / "report" / "report.md").read_text(), run)
    assert not list(run.glob(".report-*"))


def test_a_run_interrupted_while_it_ran_says_so_on_every_figure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    run = interrupted_run(tmp_path / "run", after=r"tick [1-9]\d*/")
    proc = swarm(["report", str(run)], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    pointers_hold(proc.stdout, run)
    if "no figures" in proc.stdout:  # the logger's last second was lost with it: nothing drawn
        pytest.skip(f"the recording holds no pose: {proc.stdout}")
    assert proc.stderr.splitlines() == [
        *(f"report: figure {k}/4 {stem}.png" for k, stem in enumerate(FIGURES, start=1)),
        "report: report.md",
    ]
    titles: list[str] = []

    def save(fig: Any, path: Any, dpi: int) -> None:
        texts = [fig._suptitle.get_text()] if fig._suptitle is not None else []
        titles.append(" ".join(texts + [ax.get_title() for ax in fig.axes]))
        Path(path).write_bytes(b"")  # the file it would have drawn, for the report to move into place

    monkeypatch.setattr(drawing, "save", save)
    steps: list[str] = []
    make_report(run, progress=steps.append)
    assert len(titles) == len(FIGURES)
    assert all(re.search(r"\[interrupted at \d+\.\d s", t) for t in titles), titles
    assert steps == [*(f"figure {k}/4 {stem}.png" for k, stem in enumerate(FIGURES, start=1)), "report.md"]


def test_export_holds_a_users_controller_values(swarm_run: Callable[..., RunResult], tmp_path: Path) -> None:
    overrides = {"followers.3.law": f"{LAW}:Paper", "run.duration_s": 3.0}
    res = swarm_run("fig11_obstacles", overrides=overrides)
    assert res.exit_code == 0
    proc = swarm(["export", str(res.run_dir), "--out", str(tmp_path / "run.csv")], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader((tmp_path / "run.csv").open()))
    r3 = [row for row in rows if row["robot"] == "3"]
    assert [float(row["controller_steps"]) for row in r3] == [float(k) for k in range(1, 61)]  # its 60 steps
    assert {row["controller_scale"] for row in r3} == {"1.0"}
    assert {row["controller_steps"] for row in rows if row["robot"] == "2"} == {""}  # the paper's law: none
    assert all(row["rho_m"] and row["alpha_rad"] for row in rows if row["robot"] in ("2", "3"))
    assert not list(tmp_path.glob(".*.part"))
    # compare, as it works: a line per run, then the figure
    out = tmp_path / "c.png"
    proc = swarm(["compare", str(res.run_dir), str(res.run_dir), "--out", str(out)], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    told = [
        re.findall(r"^compare:|\d+/\d+|\S+\.png", line.replace(str(res.run_dir), ""))
        for line in proc.stderr.splitlines()
    ]
    assert told == [["compare:", "1/2"], ["compare:", "2/2"], ["compare:", "c.png"]]
    assert proc.stderr.count(str(res.run_dir)) == 2  # each run named
    assert out.stat().st_size > 10_000
