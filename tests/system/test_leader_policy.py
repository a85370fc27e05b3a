"""The leader's policy and the controllers' hooks in real runs.

The figure-eight example (examples/figure_eight) flies from the command
line: two ``swarm run --mode lockstep`` runs give one digest, the engine's.
``reset()`` is called once in each agent before the run and ``close()``
once as it stops, at the run's end and at a Ctrl-C; a close that raises is
the run's controller failure, in one line. The hooked classes
(tests.helpers.hooked) write a line per call into a file: the agents are
other processes.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from formation_swarm import Engine
from formation_swarm.launch.launcher import Launch, RunResult
from tests.helpers import ROOT, hooked

pytestmark = pytest.mark.slow

SWARM = Path(sys.executable).parent / "swarm"
COMMAND = [str(SWARM)] if SWARM.exists() else [sys.executable, "-m", "formation_swarm.cli"]
EIGHT = ROOT / "examples" / "figure_eight"
SHORT = {"run.duration_s": 14.0, "leader.params.radius_m": 3.0}  # one loop of 12.6 s, then the line
HOOKED = {"leader.policy": f"{hooked.MODULE}:Leader", "controller.law": f"{hooked.MODULE}:Follower"}


def _swarm(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """A ``swarm`` command with the example on its Python path (before the session's own)."""
    path = [str(ROOT), str(EIGHT), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(path)}
    return subprocess.run([*COMMAND, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


def test_two_lockstep_runs_of_the_figure_eight_give_one_digest_the_engines(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    sets = [arg for key, value in SHORT.items() for arg in ("--set", f"{key}={value:g}")]
    summaries = []
    for i in range(2):
        args = ["run", str(EIGHT / "figure_eight.toml"), "--mode", "lockstep", "--no-logger", *sets, "--out", f"r{i}"]
        proc = _swarm(args, tmp_path)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        (header,) = [line for line in proc.stdout.splitlines() if line.startswith("[swarm] run ")]
        assert ", leader figure_eight:FigureEight, law fuzzy (V_N dynamic), folder " in header
        summaries.append(json.loads((tmp_path / f"r{i}" / "summary.json").read_text()))
    a, b = summaries
    monkeypatch.syspath_prepend(str(EIGHT))
    engine = Engine(EIGHT / "figure_eight.toml", overrides=SHORT).run()
    assert a["trajectory_digest"] == b["trajectory_digest"] == engine.trajectory_digest
    assert (a["ticks"], a["lockstep_misses"], a["controller_failures"]) == (280, 0, [])
    assert a["laws"]["leader"] == "figure_eight:FigureEight"
    assert [(e["robot"], e["formation"]) for e in a["formation_events"]] == [(1, "line"), (2, "line"), (3, "line")]


def test_each_agent_resets_and_closes_once_and_a_close_that_raises_fails_the_run(
    swarm_run: Callable[..., RunResult], tmp_path: Path
) -> None:
    log = tmp_path / "hooks.log"
    overrides = {
        **HOOKED,
        "leader.params.log": str(log),
        "controller.params.log": str(log),
        "followers.3.params.raise_in": "close",
        "run.duration_s": 3.0,
    }
    res = swarm_run("fig11_obstacles", mode="lockstep", logger=False, overrides=overrides)
    assert sorted(log.read_text().splitlines()) == ["close 1", "close 2", "close 3", "reset 1", "reset 2", "reset 3"]
    error = "close() raised RuntimeError: close failing on purpose"
    s = res.summary
    assert s["controller_failures"] == [{"robot": 3, "tick": 59, "error": error, "law": HOOKED["controller.law"]}]
    assert (res.exit_code, s["end_reason"], s["ticks"]) == (1, "duration_reached", 60)
    law = HOOKED["controller.law"]
    assert re.findall(r"robot \d+|tick \d+", s["failure"]) == ["robot 3", "tick 59"]
    assert f"({law})" in s["failure"]
    assert s["failure"].endswith(f": {error}")
    agent_log = (res.run_dir / "logs" / "agent-3.log").read_text()
    assert f"controller {HOOKED['controller.law']} failed after tick 59: {error}" in agent_log


def test_a_ctrl_c_closes_every_agents_controller(swarm_launch: Callable[..., Launch], tmp_path: Path) -> None:
    log = tmp_path / "hooks.log"
    overrides = {**HOOKED, "leader.params.log": str(log), "controller.params.log": str(log)}
    launch = swarm_launch("fig11_obstacles", mode="lockstep", logger=False, overrides=overrides)
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    launch.interrupt()
    res = launch.wait(timeout_s=60)
    assert res.exit_code == 130
    assert sorted(log.read_text().splitlines()) == ["close 1", "close 2", "close 3", "reset 1", "reset 2", "reset 3"]
