"""A follower's stops, for its stats (agents.follower_role): the ticks it held
at a standing reference and the ticks it waited ahead of its target."""

from __future__ import annotations

MAX_HOLDS = 100  # holds listed in the stats (all are counted in held_ticks)


class Stops:
    """A follower's stops, for its stats: the ticks it held at a standing
    reference, [first, last] tick of each hold (the first MAX_HOLDS), and the
    ticks it waited ahead of its target (controller.wait_ahead)."""

    def __init__(self) -> None:
        self.held_ticks = 0
        self.holds: list[list[int]] = []
        self._span: list[int] | None = None  # the hold under way, if it is recorded
        self.waited_ticks = 0

    def count(self, tick: int, *, holding: bool, waiting: bool) -> None:
        self.waited_ticks += waiting
        if not holding:
            self._span = None
            return
        self.held_ticks += 1
        if self._span is not None:
            self._span[1] = tick
        elif len(self.holds) < MAX_HOLDS:
            self._span = [tick, tick]
            self.holds.append(self._span)
