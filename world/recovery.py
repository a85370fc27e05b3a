"""How the formation comes back once a robot returns: a small windowed metric.

When a robot's agent returns (a fresh process after a restart, a session
regained after a loss, a process thawed), the world engine feeds a
:class:`Recovery` the formation error of the follower it watches at every
tick from then on: the returning follower itself, or, when the leader
returns, each of its followers (one record each). It keeps:

- the first tick the error is below ``bound_m`` (0.5 m);
- the first tick from which it stays below for ``hold_s`` (1 s): settled;
- the error at the return, ``window_s`` (5 s) after it, and the largest and
  RMS error over those ``window_s``.

No I/O, no Zenoh: the engine calls :meth:`Recovery.add` from its metrics.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

BOUND_M = 0.5  # "back in formation": the formation error below this
WINDOW_S = 5.0  # the error is summed up over this long after the return
HOLD_S = 1.0  # settled: below the bound for this long in a row


@dataclass
class Recovery:
    robot: int  # the robot that returned
    event: str  # what brought it back: "readmitted" (restart, lost session) or "thawed"
    fault: str | None  # the scheduled fault it comes back from (None: an unplanned loss)
    since_tick: int
    watched: tuple[int, ...]  # whose formation error is measured (the largest of them, if several)
    dt_s: float
    bound_m: float = BOUND_M
    window_s: float = WINDOW_S
    hold_s: float = HOLD_S
    first_below_tick: int | None = field(init=False, default=None)
    settled_tick: int | None = field(init=False, default=None)
    error_at_start_m: float | None = field(init=False, default=None)
    error_after_window_m: float | None = field(init=False, default=None)
    max_m: float = field(init=False, default=0.0)
    _below_since: int | None = field(init=False, default=None)
    _sum_sq: float = field(init=False, default=0.0)
    _n: int = field(init=False, default=0)

    def add(self, tick: int, errors: Mapping[int, float]) -> None:
        """The formation errors (m, per follower) of ``tick``."""
        if tick < self.since_tick:
            return
        err = max((errors[r] for r in self.watched if r in errors), default=None)
        if err is None:
            return
        window = round(self.window_s / self.dt_s)
        after = tick - self.since_tick
        if after == 0:
            self.error_at_start_m = err
        if after < window:
            self.max_m = max(self.max_m, err)
            self._sum_sq += err * err
            self._n += 1
        elif after == window:
            self.error_after_window_m = err
        if err < self.bound_m:
            if self.first_below_tick is None:
                self.first_below_tick = tick
            if self._below_since is None:
                self._below_since = tick
            hold = max(1, round(self.hold_s / self.dt_s))
            if self.settled_tick is None and tick - self._below_since + 1 >= hold:
                self.settled_tick = self._below_since
        else:
            self._below_since = None

    def as_dict(self) -> dict[str, object]:
        def after_s(tick: int | None) -> float | None:
            return None if tick is None else (tick - self.since_tick) * self.dt_s

        return {
            "robot": self.robot,
            "event": self.event,
            "fault": self.fault,
            "since_tick": self.since_tick,
            "since_s": self.since_tick * self.dt_s,
            "watched": list(self.watched),
            "bound_m": self.bound_m,
            "first_below_tick": self.first_below_tick,
            "first_below_after_s": after_s(self.first_below_tick),
            "settled_tick": self.settled_tick,
            "settled_after_s": after_s(self.settled_tick),
            "error_at_start_m": self.error_at_start_m,
            "window_s": self.window_s,
            "error_after_window_m": self.error_after_window_m,
            "max_in_window_m": self.max_m if self._n else None,
            "rms_in_window_m": math.sqrt(self._sum_sq / self._n) if self._n else None,
        }
