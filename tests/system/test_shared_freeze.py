"""A long freeze of one robot of a shared process, in real time: its inbox
fills (Zenoh's FIFO channel) and would block the receiving thread its
neighbours share; what arrives while it is frozen leaves the channel
(nodes.agent.hold), so they answer on."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from formation_swarm.launch.launcher import RunResult

pytestmark = pytest.mark.slow

TICKS = 360  # 18 s of sim time
FROZEN_TICKS = 300  # 15 s: the 256 messages of agent-5's channel would fill within it


def test_a_freeze_longer_than_the_inbox_holds_still_leaves_its_neighbours_flying(
    swarm_run: Callable[..., RunResult],
) -> None:
    overrides = {
        "run.robots": 11,
        "leader.formation": "line",
        "controller.lookahead_m": 1.0,
        "run.duration_s": TICKS * 0.05,
        "run.agents_per_process": 10,
    }
    res = swarm_run(
        "fig11_obstacles", logger=False, overrides=overrides, mode="realtime", faults=["freeze agent-5@1s for=15s"]
    )
    assert res.exit_code == 0, res.summary.get("failure")
    parts = {r: res.summary["parts"][f"agent-{r}"] for r in range(1, 12)}
    assert parts[5]["answered"] <= TICKS - FROZEN_TICKS + 5
    neighbours = [r for r in range(1, 11) if r != 5]
    # Before nodes.agent.hold they lost every tick from about 12 s into the freeze until the thaw.
    answered = {r: parts[r]["answered"] for r in neighbours}
    assert min(answered.values()) >= TICKS - 12, answered
