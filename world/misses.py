"""The lockstep deadlines each robot missed, and how many of them a
scheduled fault explains.

A miss is a scheduled fault's doing when the robot was just thawed or
re-admitted after one (its first answer since is not in), or when a kill,
restart, freeze or partition that concerns it covers the tick or ended less
than SETTLE_S of sim time before (a fault on the logger concerns every
robot: in lockstep their telemetry waits for it). Any other miss stopped
the robot for a step no schedule says: the run is not reproducible
(runtime.summary).

No Zenoh and no clock here: world.tick counts each miss.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from formation_swarm.common.faults import Fault

EXPLAINING_KINDS = frozenset({"kill", "restart", "freeze", "partition"})
SETTLE_S = 1.0  # sim time after such a fault's end whose misses are still its doing


class Misses:
    """Each robot's misses: ``{"misses", "by_faults", "first_tick"}``, the
    last the tick of its first miss no fault explains (None: none)."""

    def __init__(self, faults: Iterable[Fault], dt_s: float) -> None:
        self.windows = [(f, f.start_tick(dt_s), f.end_tick(dt_s)) for f in faults if f.kind in EXPLAINING_KINDS]
        self.settle_ticks = math.ceil(SETTLE_S / dt_s)
        self.by_robot: dict[int, dict[str, Any]] = {}

    def count(self, rid: int, tick: int, *, returning: bool) -> None:
        """``rid`` missed the deadline of ``tick``; ``returning``: just back from a scheduled fault."""
        m = self.by_robot.setdefault(rid, {"misses": 0, "by_faults": 0, "first_tick": None})
        m["misses"] += 1
        if returning or self.explained(rid, tick):
            m["by_faults"] += 1
        elif m["first_tick"] is None:
            m["first_tick"] = tick

    def explained(self, rid: int, tick: int) -> bool:
        """Whether a scheduled fault explains a miss of ``rid`` at ``tick``."""
        return any(
            start <= tick and (end is None or tick < end + self.settle_ticks) and f.applies_to(rid)
            for f, start, end in self.windows
        )

    def stats(self) -> dict[str, dict[str, Any]]:
        """By robot id (a string, as JSON keys): the robots that missed a deadline."""
        return {str(rid): dict(m) for rid, m in sorted(self.by_robot.items())}
