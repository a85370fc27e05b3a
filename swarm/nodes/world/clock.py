"""The world's two clocks: when a tick starts, how long its answers are
waited for, when Status "running" goes out. The loop (nodes.world.node)
asks its clock; the tick (world.tick) decides the rest.

Lockstep: tick k starts as soon as tick k - 1 is stepped; the clock waits
until every live agent has answered tick k or ``lockstep_deadline_s``
passes (the miss is counted, that robot is stopped for the step; after
world.stalls.STALL_AFTER_MISSES in a row it is stalled, no longer waited
for until it answers again). Real
time: tick k starts k * dt_s after the loop did; nobody is waited for; the
tick stamps commands with that wall time and stops a robot whose command is
older than ``stale_after_s``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import zenoh

from formation_swarm.runtime.proc import StopEvent
from formation_swarm.world.tick import WorldTick

STATUS_PERIOD_S = 0.25
# Real time: Status "running" every tick up to this many robots, beyond it every
# STATUS_PERIOD_S like lockstep: each one is routed to every agent, whose
# status callback thread then wakes and takes the GIL from its loop.
STATUS_EVERY_TICK_UP_TO = 25


def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile of ``values`` (nearest rank); NaN when there are none."""
    if not values:
        return math.nan
    ranked = sorted(values)
    return ranked[min(len(ranked) - 1, max(0, math.ceil(q / 100.0 * len(ranked)) - 1))]


class Clock:
    """What both clocks share: the loop's start, the Status period, the timing figures."""

    name = ""
    # The logger's ground truth, batched: lockstep may hold the run back rather
    # than lose it (a dropped batch took up to 200 ticks out of the recording).
    truth_congestion = zenoh.CongestionControl.BLOCK

    def __init__(
        self, tick: WorldTick, drain: Callable[[float], None], stop: StopEvent, *, deadline_s: float, thaw_s: float
    ) -> None:
        self.tick = tick
        self.drain = drain  # handles what has arrived, waiting for it until a time of time.monotonic()
        self.stop = stop
        self.deadline_s = deadline_s  # lockstep: the longest wait for a tick's answers
        self.thaw_s = thaw_s  # a robot just thawed may wait for its SIGCONT: its first answer gets longer
        self.period_s = tick.setup.dt_s
        self.started = time.monotonic()
        self.next_status = self.started
        self.wait_s = 0.0  # lockstep: time waiting for the agents' answers
        self.late_ticks = 0
        self.max_tick_lateness_s = 0.0
        self.lateness_s: list[float] = []  # real time: each tick's lateness, for its percentiles

    def begin(self) -> None:
        """The loop starts now."""
        self.started = self.next_status = time.monotonic()

    def start_tick(self) -> float:
        """When the current tick starts (``time.monotonic()``)."""
        return time.monotonic()

    def answers(self) -> None:
        """Take the tick's answers."""
        self.drain(0.0)

    def status_due(self, now: float) -> bool:
        """Whether Status "running" goes out this tick (started at ``now``)."""
        if now >= self.next_status:
            self.next_status = now + STATUS_PERIOD_S
            return True
        return False

    def before_step(self, send_truth: Callable[[], None]) -> None:
        """The tick's answers are in and its truth taken; the step comes next."""

    def p99_lateness_s(self) -> float:
        return percentile(self.lateness_s, 99.0)


class LockstepClock(Clock):
    """Tick k + 1 when every live agent has answered tick k, or at the deadline."""

    name = "lockstep"

    def answers(self) -> None:
        tick = self.tick
        t_wait = time.perf_counter()
        deadline = time.monotonic() + self.deadline_s
        thaw_deadline = time.monotonic() + self.thaw_s
        # Robots only leave this list while the world waits (they answer, die or
        # freeze; none is revived before the next tick): it is filtered, not rebuilt.
        waiting = tick.engine.alive_ids
        while not self.stop.is_set():
            waiting = tick.waiting(waiting)
            if not waiting:
                break
            until = thaw_deadline if tick.thawing(waiting) else deadline
            if time.monotonic() >= until:
                for rid in tick.miss(waiting):
                    print(
                        f"world: robot {rid} did not answer within {self.thaw_s:g} s "
                        f"of its thaw at t={tick.engine.time_s:.2f} s; a miss",
                        flush=True,
                    )
                for line in tick.stall(waiting):
                    print(f"world: {line}", flush=True)
                break
            self.drain(until)
        self.wait_s += time.perf_counter() - t_wait


class RealTimeClock(Clock):
    """Tick k at k * dt_s of wall time after the start, whatever the agents do."""

    name = "realtime"
    # Late truth is worth less than the run's pace: a batch the router cannot take is dropped.
    truth_congestion = zenoh.CongestionControl.DROP

    def start_tick(self) -> float:
        """Wait for this tick's time, handling commands meanwhile; count how late it starts."""
        tick_start = self.started + self.tick.engine.tick * self.period_s
        now = time.monotonic()
        while now < tick_start and not self.stop.is_set():
            self.drain(tick_start)
            now = time.monotonic()
        lateness = now - tick_start
        self.max_tick_lateness_s = max(self.max_tick_lateness_s, lateness)
        self.lateness_s.append(lateness)
        if lateness > 0.5 * self.period_s:
            self.late_ticks += 1
        return now

    def status_due(self, now: float) -> bool:
        every_tick = len(self.tick.setup.robots) <= STATUS_EVERY_TICK_UP_TO
        return super().status_due(now) or every_tick

    def before_step(self, send_truth: Callable[[], None]) -> None:
        send_truth()  # no one waits for the next tick's observations: now


CLOCKS: dict[str, type[Clock]] = {LockstepClock.name: LockstepClock, RealTimeClock.name: RealTimeClock}
