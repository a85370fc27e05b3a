"""Lockstep robots that stop answering while their agent's token stays, and
robots lost after such a silence.

A robot that misses ``STALL_AFTER_MISSES`` lockstep deadlines in a row is
**stalled**: it stays stopped and the world no longer waits for it, until a
command of its is taken again (on time or late); it gets an observation
only every ``STALLED_OBS_PERIOD_S`` of wall time meanwhile. What keeps a token while
nothing answers: a process hung or cut off before its session's lease ends
(10 s), or a stolen login holding the token of a robot whose agent died.
While every robot a tick would wait for is stalled, the world waits for them
all as before: nothing would move without them, and their return (a
partition's end) is what the run needs.

A stalled robot whose token then goes has lost its session at the lease's
end: a partition, or a freeze longer than the lease, and its process may
well live and come back once the link does. It is **awaited**: the world
holds its clock at the next tick's start until it is re-admitted, at most
``LOST_WAIT_S`` of wall time. A robot whose token goes while it answered is
not awaited: a process that ends takes its token within milliseconds.

No Zenoh and no clock here: world.tick feeds the misses, the answers and
the tokens; the world process (nodes.world.node) does the holding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

STALL_AFTER_MISSES = 3  # lockstep deadlines missed in a row: 6 s at the default 2 s deadline
LOST_WAIT_S = 30.0  # wall seconds the world holds its clock for an awaited robot
# A stalled robot gets an observation at most this often (wall s), enough to
# answer again: one every tick of a world no longer waiting for it would fill
# the buffers of a hung agent's link, and the world's puts (BLOCK) would wait.
STALLED_OBS_PERIOD_S = 0.5


@dataclass
class Stalls:
    """The stalled and awaited robots of one lockstep run, and what happened to them."""

    in_row: dict[int, int] = field(default_factory=dict)  # deadlines missed in a row, by robot
    stalled: set[int] = field(default_factory=set)
    awaited: dict[int, float] = field(default_factory=dict)  # robot -> the wall time its wait ends
    events: list[dict[str, Any]] = field(default_factory=list)  # {robot, tick, time_s, event, ...}
    held_s: float = 0.0  # wall time the clock was held for awaited robots
    last_obs: dict[int, float] = field(default_factory=dict)  # stalled robot -> wall time of its last observation

    def _event(self, event: str, rid: int, tick: int, time_s: float, **extra: Any) -> None:
        self.events.append({"robot": rid, "tick": tick, "time_s": time_s, "event": event, **extra})

    def missed(self, rids: list[int], tick: int, time_s: float) -> list[int]:
        """``rids`` missed the deadline of ``tick``; those stalled by it."""
        now_stalled = []
        for rid in rids:
            n = self.in_row[rid] = self.in_row.get(rid, 0) + 1
            if n == STALL_AFTER_MISSES and rid not in self.stalled:
                self.stalled.add(rid)
                self._event("stalled", rid, tick, time_s, misses=n)
                now_stalled.append(rid)
        return now_stalled

    def heard(self, rid: int, tick: int, time_s: float) -> bool:
        """A command of ``rid`` was taken; whether that ends its stall."""
        self.in_row.pop(rid, None)
        if rid not in self.stalled:
            return False
        self.stalled.discard(rid)
        self.last_obs.pop(rid, None)
        self._event("answering again", rid, tick, time_s)
        return True

    def wait_for(self, waiting: list[int], observed: list[int]) -> list[int]:
        """Of the robots a tick still ``waiting`` for, those it waits for: all
        but the stalled ones, unless every robot it ``observed`` is stalled."""
        if not self.stalled or all(rid in self.stalled for rid in observed):
            return waiting
        return [rid for rid in waiting if rid not in self.stalled]

    def observe(self, observed: list[int], wall_s: float) -> list[int]:
        """Of the robots a tick would observe, those it does: a stalled one every
        STALLED_OBS_PERIOD_S, unless every one is stalled (then each tick waits
        for them all, and observes them all)."""
        if not self.stalled or all(rid in self.stalled for rid in observed):
            return observed
        out = []
        for rid in observed:
            if rid in self.stalled:
                if wall_s < self.last_obs.get(rid, -math.inf) + STALLED_OBS_PERIOD_S:
                    continue
                self.last_obs[rid] = wall_s
            out.append(rid)
        return out

    def lost(self, rid: int, tick: int, time_s: float, wall_s: float) -> bool:
        """``rid``'s token went (no kill called); whether it is awaited (it was stalled)."""
        self.in_row.pop(rid, None)
        if rid not in self.stalled:
            return False
        self.stalled.discard(rid)
        self.awaited[rid] = wall_s + LOST_WAIT_S
        self._event("lost while stalled", rid, tick, time_s, awaited_s=LOST_WAIT_S)
        return True

    def back(self, rid: int) -> None:
        """``rid`` was re-admitted (or stopped for good by a fault): no longer awaited."""
        self.in_row.pop(rid, None)
        self.stalled.discard(rid)
        self.awaited.pop(rid, None)

    def overdue(self, tick: int, time_s: float, wall_s: float) -> list[int]:
        """The awaited robots whose wait ended by ``wall_s``: no longer awaited."""
        late = sorted(rid for rid, until in self.awaited.items() if wall_s >= until)
        for rid in late:
            del self.awaited[rid]
            self._event("not back in time", rid, tick, time_s, awaited_s=LOST_WAIT_S)
        return late

    def until(self) -> float:
        """The wall time the first awaited robot's wait ends (inf: none awaited)."""
        return min(self.awaited.values(), default=math.inf)
