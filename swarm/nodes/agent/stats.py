"""An agent's counters on disk (``--stats``): written at exit and, while the
run goes on, at the run's first message, every STATS_PERIOD_S and a little
after each link fault's window ends, so that a SIGKILLed agent (a kill or
restart fault) leaves what it counted until then. Each write goes through
its own thread: a slow disk stalls no tick. A step that does not return
(nodes.agent.watch) is noted over the last write: ``in_step``.
"""

from __future__ import annotations

import collections
import math
import time
from collections.abc import Callable, Iterable
from typing import Any

from formation_swarm.protocol.links import COUNTS_FINAL_AFTER_TICKS
from formation_swarm.runtime.proc import JsonWriter

# Wall time between two writes of the counters while the run goes on: one
# write (JSON, then a rename over the old file) costs 0.3-1 ms of CPU here, so
# beyond 25 robots it is spaced out to STATS_S_PER_ROBOT per robot (4 s for 100).
STATS_PERIOD_S = 1.0
STATS_S_PER_ROBOT = 0.04
# The file's keys, in order (formation_swarm.runtime.summary reads them): the
# process's (robot, role, lockstep, busy_s, cpu_s, loop_cpu_s, in_step,
# world_back_after_s, rejected, memory_given_back) and its role's (agents.role_base.RoleBase.stats).
KEYS = (
    "robot",
    "role",
    "lockstep",
    "answered",
    "last_tick",
    "superseded",
    "ekf_resets",
    "held_ticks",
    "holds",
    "waited_ticks",
    "busy_s",
    "cpu_s",
    "loop_cpu_s",
    "step_time",
    "in_step",
    "formation",
    "formation_changes",
    "controller_failure",
    "world_back_after_s",
    "links",
    "rejected",
    "memory_given_back",
)


class StatsFile:
    def __init__(self, path: str | None, robots: int, fault_ends: Iterable[int]) -> None:
        self.path = path
        self.writer = JsonWriter(path, name="stats-writer")
        self.period_s = max(STATS_PERIOD_S, STATS_S_PER_ROBOT * robots)
        self.written_at = -math.inf  # the first pass of the loop writes
        self.last: dict[str, Any] | None = None  # the last snapshot written
        self.noted = False  # the file says a call is under way (note): the next pass writes it over
        # A link fault's counts are final a little after its window ends: the stats
        # are written then, so an agent a later fault kills leaves them whole.
        self.at_ticks = collections.deque(sorted({end + COUNTS_FINAL_AFTER_TICKS for end in fault_ends}))

    def after(self, tick: int | None, stats: Callable[[], dict[str, Any]], now: bool = False) -> None:
        """After a pass of the loop that answered ``tick`` (None: none): write
        ``stats()`` if it is time, or ``now``."""
        fault_over = False
        while tick is not None and self.at_ticks and self.at_ticks[0] <= tick:
            self.at_ticks.popleft()
            fault_over = True
        if self.path and (now or fault_over or self.noted or time.monotonic() - self.written_at >= self.period_s):
            self.noted = False
            self.last = self.writer.offer(stats())
            self.written_at = time.monotonic()

    def note(self, in_step: dict[str, Any]) -> None:
        """The last snapshot again, with the call under way (from another
        thread: the loop's is held by that call)."""
        if self.last is not None:
            self.noted = True
            self.writer.offer({**self.last, "in_step": in_step})

    def close(self, last: dict[str, Any]) -> None:
        """The last write, after any older snapshot."""
        self.writer.close(last)
