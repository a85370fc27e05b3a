"""The engine (formation_swarm.Engine) is a lockstep run: for fig11_obstacles,
seeds 1-3, with an observation drop and an agent restart, its trajectory
digest and its figures are those of ``swarm run --mode lockstep``'s real
processes."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from formation_swarm import Engine
from formation_swarm.launch.launcher import RunResult

FAULTS = ["drop obs:2@3s for=4s p=0.3", "restart agent-3@20s after=1s"]


def _fault_events(s: dict[str, Any]) -> list[list[tuple[Any, ...]]]:
    """What the world did for each fault, tick by tick."""
    return [[(e["event"], e["robot"], e["tick"]) for e in f["events"]] for f in s["faults"]]


@pytest.mark.slow  # three real runs, about 5 s each here
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_engines_digest_is_a_lockstep_runs(swarm_run: Callable[..., RunResult], seed: int) -> None:
    real = swarm_run("fig11_obstacles", mode="lockstep", seed=seed, logger=False, faults=FAULTS).summary
    res = Engine("fig11_obstacles", seed=seed, faults=FAULTS).run()
    again = res.summary
    assert real["lockstep_misses"] == again["lockstep_misses"] == 0
    assert (real["exit_code"], real["end_reason"], real["ticks"]) == (res.exit_code, res.end_reason, res.ticks)
    assert real["trajectory_digest"] == res.trajectory_digest
    assert real["robot_digests"] == again["robot_digests"]
    for key in ("followers", "min_distance_m", "collisions", "obstacle_collisions", "controller_failures"):
        assert real[key] == again[key], key
    # (Within one tick, the world lists formation events in the order the answers came.)
    by_tick = sorted(real["formation_events"], key=lambda e: (e["tick"], e["robot"]))
    assert by_tick == sorted(again["formation_events"], key=lambda e: (e["tick"], e["robot"]))
    assert _fault_events(real) == _fault_events(again)
    drop = real["faults"][0]["counts"]
    assert drop == again["faults"][0]["counts"]
    assert drop["dropped"] > 0  # the drop did drop
    executed = [[(e["event"], e["process"], e["tick"]) for e in f.get("executed", [])] for f in real["faults"]]
    assert executed == [[], [("killed", "agent-3", 400), ("started", "agent-3.2", 420)]]
    assert [(e["event"], e["process"], e["tick"]) for e in res.events] == executed[1]
