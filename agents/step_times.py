"""How long a robot's decisions take: its controller's ``step`` (a
follower's) or its policy's (the leader's), timed by its role.

:class:`StepTimes` keeps the number of steps, the largest and its tick, how
many took longer than the tick, and a histogram (BINS_PER_OCTAVE bins per
doubling) whose median bin's mean is the median said. While a call runs,
``current`` holds its tick, start and name: the agent's watchdog
(nodes.agent.watch) reads it from another thread, so that a step that never
returns is in the agent's stats. A call during which the process was
stopped (a freeze: ``continued``) is not counted. No I/O.
"""

from __future__ import annotations

import math
import time
from typing import Any

BINS_PER_OCTAVE = 8  # a bin spans 9% of its times: the median is its bin's mean
SHORTEST_S = 1e-6  # the first bin's lower edge; a shorter step falls in it
# A step longer than the tick is the controller's doing, and said in the log,
# when it computed for longer than the tick (its thread's CPU time) or was
# blocked for this many ticks: a busy machine stretches a step's wall time
# without either, and the stats count every step longer than the tick anyway.
BLOCKED_TICKS = 10


class StepTimes:
    """A role's step times; ``tick_s``: the run's tick (dt_s)."""

    def __init__(self, tick_s: float) -> None:
        self.tick_s = tick_s
        self.steps = 0
        self.over_tick = 0  # steps longer than the tick
        self.max_s = 0.0
        self.max_tick: int | None = None  # the tick of the longest
        self._bins: dict[int, list[float]] = {}  # bin -> [steps, their sum in s]
        # The call under way, (tick, perf_counter at its start, its name), one
        # tuple: another thread reads it whole.
        self.current: tuple[int, float, str] | None = None
        self.cpu_started = 0.0  # the calling thread's CPU time at the call's start
        self.cpu_s = 0.0  # the CPU time of the last call stopped
        self.said = False  # a step was said slow in the log (once per role)
        self.stopped_in_call = False  # the process was stopped (SIGSTOP) during the call under way

    def start(self, tick: int, call: str = "step") -> None:
        """A call of the tick ``tick`` starts."""
        self.current = (tick, time.perf_counter(), call)
        self.cpu_started = time.thread_time()

    def stop(self, counted: bool = True) -> float | None:
        """The call under way ended (returned or raised); how long it took (s),
        if it is counted: a step (``counted``; a ``prepare`` is not), during
        which the process was not stopped (its time would hold the stop)."""
        if self.current is None:
            return None
        tick, started, _ = self.current
        took_s = time.perf_counter() - started
        self.cpu_s = time.thread_time() - self.cpu_started
        self.current = None
        counted, self.stopped_in_call = counted and not self.stopped_in_call, False
        if not counted:
            return None
        self.add(tick, took_s)
        return took_s

    def continued(self) -> None:
        """The process was stopped and continued (SIGCONT: a freeze): the call
        under way, if any, is not counted."""
        self.stopped_in_call = self.current is not None

    def first_slow(self, who: str, tick: int) -> str | None:
        """Stop the step under way (of ``tick``); a line for the log when it
        is the first longer than the tick by the controller's own doing: it
        computed longer than the tick, or was blocked for BLOCKED_TICKS ticks
        (``who``: "controller pkg.mod:Cls")."""
        took_s = self.stop()
        if took_s is None or took_s <= self.tick_s or self.said:
            return None
        if self.cpu_s <= self.tick_s and took_s < BLOCKED_TICKS * self.tick_s:
            return None  # the machine's doing as likely as the controller's
        self.said = True
        return (
            f"{who} took {took_s:.3f} s ({self.cpu_s:.3f} s of CPU) in its step of tick {tick}, longer than the "
            f"tick ({self.tick_s:g} s); its step times are in this agent's stats (step_time)"
        )

    def add(self, tick: int, took_s: float) -> None:
        """A step of tick ``tick`` that took ``took_s``."""
        self.steps += 1
        self.over_tick += took_s > self.tick_s
        if took_s > self.max_s:
            self.max_s, self.max_tick = took_s, tick
        b = int(math.log2(max(took_s, SHORTEST_S) / SHORTEST_S) * BINS_PER_OCTAVE)
        counts = self._bins.get(b)
        if counts is None:
            self._bins[b] = [1, took_s]
        else:
            counts[0] += 1
            counts[1] += took_s

    def median_s(self) -> float | None:
        """The mean of the bin that holds the median step (None: no step yet)."""
        half, seen = (self.steps + 1) / 2, 0
        for b in sorted(self._bins):
            n, total = self._bins[b]
            seen += int(n)
            if seen >= half:
                return total / n
        return None

    def in_call(self) -> dict[str, Any] | None:
        """The call under way (None: none): its tick, name and time so far (s)."""
        current = self.current
        if current is None:
            return None
        tick, started, call = current
        return {"tick": tick, "call": call, "for_s": time.perf_counter() - started}

    def stats(self) -> dict[str, Any]:
        """For the agent's stats (``step_time``)."""
        return {
            "steps": self.steps,
            "median_s": self.median_s(),
            "max_s": self.max_s if self.steps else None,
            "max_tick": self.max_tick,
            "over_tick": self.over_tick,
            "tick_s": self.tick_s,
        }
