"""A follower's controller too slow for its run, or one that hangs in
``step``, in real runs (docs/controllers.md, "When a controller fails").

In lockstep a robot that misses a deadline no scheduled fault explains
makes the run not reproducible: it fails, naming the robot, its law, its
step time and ``run.lockstep_deadline_s``. In real time a controller whose
steps take longer than the tick is named with its median and longest step.
A controller that never returns from ``step`` is named as hung, and its
agent leaves without it: the run ends well within the launcher's stop
timeout plus 10 s. Before, each of these runs exited 0 and named no one.

The test controllers (tests.helpers.slow_controllers) are imported by the
agents from the launcher's Python path, as in test_user_controllers.
"""

from __future__ import annotations

import io
import time
from collections.abc import Callable

import pytest

from formation_swarm.launch.console import print_result
from formation_swarm.launch.launcher import RunResult
from formation_swarm.launch.processes import END_GRACE_S, STOP_GRACE_S
from formation_swarm.runtime.children import KILLED_AT_STOP_TIMEOUT
from formation_swarm.runtime.process import EXIT_HUNG
from tests.helpers.slow_controllers import LAW

FIG11 = "fig11_obstacles"  # 1 leads, 2 and 3 follow; dt 0.05 s
SLOW, HUNG = f"{LAW}:Slow", f"{LAW}:Hung"
STOP_TIMEOUT_S = END_GRACE_S + STOP_GRACE_S + 1.0  # the launcher's, from the world's end to its SIGKILL


def _printed(res: RunResult) -> str:
    out = io.StringIO()
    print_result(res, out)
    return out.getvalue()


def test_a_lockstep_step_longer_than_the_deadline_makes_the_run_not_reproducible(
    swarm_run: Callable[..., RunResult],
) -> None:
    """Robot 3's step sleeps 0.6 s from its 51st call (tick 50) on; the deadline is 0.5 s."""
    overrides = {
        "followers.3.law": SLOW,
        "followers.3.params.from_step": 50,
        "followers.3.params.sleep_s": 0.6,
        "run.lockstep_deadline_s": 0.5,
        "run.duration_s": 3.0,
    }
    res = swarm_run(FIG11, overrides=overrides, logger=False)
    s = res.summary
    assert (res.exit_code, s["exit_code"], s["end_reason"]) == (1, 1, "duration_reached")
    [late] = [e for e in s["not_reproducible"] if e["robot"] == 3]  # a loaded machine may make another one miss too
    assert (late["law"], late["role"], late["first_tick"], late["deadline_s"]) == (SLOW, "follower", 50, 0.5)
    assert 3 <= late["misses"] <= 10  # each of ticks 50-59, unless it stalled (3 in a row unanswered)
    assert 0.6 <= late["step_max_s"] < 1.5
    assert s["step_times"]["3"]["steps"] >= 53
    assert (s["hung_controllers"], s["controller_failures"]) == ([], [])
    failed = next(line for line in _printed(res).splitlines() if line.startswith("  failed: "))
    assert f"not reproducible: robot 3's controller ({SLOW}) missed " in failed
    assert "from tick 50: its step took " in failed
    assert "and run.lockstep_deadline_s is 0.5 s" in failed


def test_a_real_time_step_longer_than_the_tick_is_named_with_its_median_and_longest(
    swarm_run: Callable[..., RunResult],
) -> None:
    """Robot 3's step sleeps 0.6 s from its 21st call on, twelve times the tick:
    blocked long enough for its log to blame it (agents.step_times.BLOCKED_TICKS)."""
    overrides = {
        "followers.3.law": SLOW,
        "followers.3.params.from_step": 20,
        "followers.3.params.sleep_s": 0.6,
        "run.duration_s": 4.0,
    }
    res = swarm_run(FIG11, mode="realtime", overrides=overrides, logger=False)
    s = res.summary
    assert res.exit_code == 0  # real time promises no repeat: said, not a failure
    [slow] = [c for c in s["slow_controllers"] if c["robot"] == 3]
    assert (slow["law"], slow["tick_s"]) == (SLOW, 0.05)
    assert 3 <= slow["over_tick"] <= 6  # 3 s of 0.6 s steps
    assert slow["median_s"] < 0.05 <= 0.6 <= slow["max_s"] < 2.0  # 20 quick steps and a few slow ones
    assert s["not_reproducible"] == []
    assert f"  slow controller: robot 3's controller ({SLOW}) took longer than the tick (0.05 s) in " in _printed(res)
    log = (res.run_dir / "logs" / "agent-3.log").read_text()
    took = log.split(f"controller {SLOW} took ", 1)[1]
    assert float(took.split()[0]) >= 0.6  # seconds, asleep 0.6 s
    assert ", longer than the tick (0.05 s); its step times are in this agent's stats (step_time)" in log


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_a_controller_hung_in_step_is_named_and_its_agent_leaves(
    swarm_run: Callable[..., RunResult], mode: str
) -> None:
    """Robot 3's controller spins for ever in its 21st step (``while True: pass``)."""
    overrides = {"followers.3.law": HUNG, "run.duration_s": 3.0, "run.lockstep_deadline_s": 0.5}
    started = time.monotonic()
    res = swarm_run(FIG11, mode=mode, overrides=overrides, logger=mode == "lockstep", timeout_s=120)
    took_s = time.monotonic() - started
    s = res.summary
    print(f"{mode}: the run took {took_s:.1f} s; {s['failure']}")
    assert took_s <= STOP_TIMEOUT_S + 10.0
    assert (res.exit_code, s["end_reason"], s["ticks"]) == (1, "duration_reached", 60)
    [hung] = s["hung_controllers"]
    assert (hung["robot"], hung["law"], hung["process"], hung["call"], hung["ended"]) == (
        3,
        HUNG,
        "agent-3",
        "step",
        "left",
    )
    assert hung["tick"] == 20 if mode == "lockstep" else hung["tick"] >= 20  # real time may skip an observation
    assert hung["for_s"] >= 2.0
    assert s["processes"]["agent-3"]["exit_code"] == EXIT_HUNG
    assert [e for e in s["events"] if e.get("event") == KILLED_AT_STOP_TIMEOUT] == []
    if mode == "lockstep":
        assert [e["robot"] for e in s["not_reproducible"] if e["robot"] == 3] == [3]
    printed = _printed(res)
    assert f"  failed: robot 3's controller ({HUNG}) hung in its step of tick {hung['tick']} (" in printed
    log = (res.run_dir / "logs" / "agent-3.log").read_text()
    assert f"controller {HUNG} hung: still in its step of tick {hung['tick']} after " in log
