"""The leader's formation decision: triangle normally, line near obstacles.

Only the leader senses obstacles (paper Fig. 11). While any obstacle is in
its sensing range it flies the avoidance formation; once none has been in
range for ``clear_after_s`` it goes back to its normal formation.

The code travels over one-way links that may drop: the leader repeats it
(:class:`CodeRepeats`), at every tick for a while after each change, so a
drop delays a change by a tick, and then at a slower heartbeat, so a change
is never lost and steady flight does not load the network.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from formation_swarm.common.checks import non_negative, positive


@dataclass
class FormationSwitch:
    normal_code: int
    avoid_code: int | None
    clear_after_s: float
    dt_s: float
    code: int = field(init=False)
    _clear_s: float = field(init=False, default=0.0)

    def __post_init__(self) -> None:
        positive("clear_after_s", self.clear_after_s)
        positive("dt_s", self.dt_s)
        self.code = self.normal_code

    def step(self, obstacles_in_range: Sequence[object]) -> int:
        """The code to fly this tick, given the obstacles sensed this tick."""
        if self.avoid_code is None:
            return self.code
        if obstacles_in_range:
            self.code = self.avoid_code
            self._clear_s = 0.0
        elif self.code == self.avoid_code:
            self._clear_s += self.dt_s
            if self._clear_s >= self.clear_after_s - 1e-9:
                self.code = self.normal_code
        return self.code


@dataclass
class CodeRepeats:
    """When the leader sends its code: every tick for ``burst_s`` after a change
    (and after the start), then every ``period_s``."""

    burst_s: float
    period_s: float
    dt_s: float
    _code: int | None = field(init=False, default=None)
    _since: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        non_negative("code_burst_s", self.burst_s)
        positive("code_period_s", self.period_s)
        positive("dt_s", self.dt_s)
        self._burst = round(self.burst_s / self.dt_s)
        self._period = max(1, round(self.period_s / self.dt_s))

    def due(self, code: int) -> bool:
        """Whether to send ``code`` this tick (call once per tick)."""
        if code != self._code:
            self._code, self._since = code, 0
        else:
            self._since += 1
        return self._since <= self._burst or (self._since - self._burst) % self._period == 0
