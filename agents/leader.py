"""The leader's formation decision: triangle normally, line near obstacles.

Only the leader senses obstacles (paper Fig. 11). While any obstacle is in
its sensing range it flies the avoidance formation; once none has been in
range for ``clear_after_s`` it goes back to its normal formation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from swarm.checks import positive


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
