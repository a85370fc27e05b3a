"""Controllers too slow for their run, in the summary (runtime.summary.slow)
and on the console: a lockstep robot whose misses no scheduled fault
explains (not reproducible), a real-time controller slower than the tick,
a controller that hung; read from the world's and the agents' stats."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from formation_swarm.launch.console import describe_event, print_result
from formation_swarm.launch.launcher import RunResult
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.children import KILLED_AT_STOP_TIMEOUT
from formation_swarm.runtime.summary.slow import (
    KILLED,
    LEFT,
    hung_controllers,
    not_reproducible,
    slow_controllers,
    step_times,
)
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS

LAW = "tests.helpers.slow_controllers:Slow"
FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml", overrides={"followers.3.law": LAW})


def _step_time(steps: int, median_s: float, max_s: float, over_tick: int) -> dict[str, Any]:
    """An agent's ``step_time`` (agents.step_times.StepTimes.stats)."""
    return dict(steps=steps, median_s=median_s, max_s=max_s, max_tick=59, over_tick=over_tick, tick_s=0.05)


def _parts(mode: str, **agent_3: Any) -> dict[str, Any]:
    return {
        "world": {
            "mode": mode,
            "robot_misses": {
                "1": {"misses": 2, "by_faults": 2, "first_tick": None},  # a freeze's: not the run's fault
                "3": {"misses": 41, "by_faults": 1, "first_tick": 20},
            },
        },
        "agent-1": {"robot": 1, "role": "leader", "step_time": _step_time(60, 2e-5, 1e-4, 0)},
        "agent-3": {"robot": 3, "role": "follower", "step_time": _step_time(60, 2.5, 2.51, 40), **agent_3},
        "logger": {},
    }


def test_a_lockstep_robots_misses_no_fault_explains_make_the_run_not_reproducible() -> None:
    parts = _parts("lockstep")
    [entry] = not_reproducible(parts["world"], parts, FIG11)
    assert entry == {
        "robot": 3,
        "role": "follower",
        "law": LAW,
        "misses": 40,
        "first_tick": 20,
        "step_median_s": 2.5,
        "step_max_s": 2.51,
        "deadline_s": 2.0,
    }
    failure = summary_mod.run_failed(parts, FIG11)
    assert failure is not None
    assert failure.startswith(f"not reproducible: robot 3's controller ({LAW}) missed 40 lockstep deadlines")
    assert "from tick 20: its step took 2.50 s (median; longest 2.51 s), and run.lockstep_deadline_s is 2 s" in failure
    assert slow_controllers(parts["world"], parts, FIG11) == []  # lockstep: the deadline is what counts


def test_a_real_time_controller_over_the_tick_is_named_but_does_not_fail_the_run(tmp_path: Path) -> None:
    parts = _parts("realtime")
    slow = slow_controllers(parts["world"], parts, FIG11)
    assert [(s["robot"], s["law"], s["over_tick"], s["steps"], s["median_s"], s["max_s"]) for s in slow] == [
        (3, LAW, 40, 60, 2.5, 2.51)
    ]
    assert not_reproducible(parts["world"], parts, FIG11) == []
    assert summary_mod.run_failed(parts, FIG11) is None
    out = io.StringIO()
    print_result(RunResult(tmp_path, {"ticks": 60, "mode": "realtime", "slow_controllers": slow}, 0), out)
    assert (
        f"  slow controller: robot 3's controller ({LAW}) took longer than the tick (0.05 s) in 40 of 60 steps: "
        "median 2.50 s, longest 2.51 s\n"
    ) in out.getvalue()


def test_a_controller_that_hung_is_named_whether_its_agent_left_or_was_killed(tmp_path: Path) -> None:
    call = {"tick": 20, "call": "step", "for_s": 8.07}
    left = _parts("realtime", in_step={**call, "left": True})
    [hung] = hung_controllers(left, [], FIG11)
    assert hung == {"robot": 3, "role": "follower", "law": LAW, "process": "agent-3", **call, "ended": LEFT}
    killed = _parts("realtime", in_step=call)
    assert hung_controllers(killed, [], FIG11) == []  # a note of a call that was under way, no hang
    events = [{"event": KILLED_AT_STOP_TIMEOUT, "process": "agent-3"}]
    [hung] = hung_controllers(killed, events, FIG11)
    assert hung["ended"] == KILLED
    failure = summary_mod.run_failed(killed, FIG11, events)
    assert failure is not None
    assert failure.startswith(f"robot 3's controller ({LAW}) hung in its step of tick 20 (8.07 s in it; its agent")
    # The console says the hang in its failed line, not the kill among the events.
    summary = {"ticks": 60, "failure": failure, "events": events, "hung_controllers": [hung]}
    out = io.StringIO()
    print_result(RunResult(tmp_path, summary, 1), out)
    assert KILLED_AT_STOP_TIMEOUT not in out.getvalue()
    assert "event:" not in out.getvalue()
    assert describe_event(events[0]).startswith("agent-3 did not leave within the stop timeout")


def test_a_restarted_robots_step_times_add_up() -> None:
    parts = {
        "agent-3": {"robot": 3, "step_time": _step_time(40, 0.001, 0.002, 0)},
        "agent-3.2": {"robot": 3, "step_time": _step_time(20, 0.5, 2.5, 10)},
    }
    assert step_times(parts) == {"3": {**_step_time(60, 0.001, 2.5, 10)}}
