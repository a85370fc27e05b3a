"""A robot's recorded commands beside its replayed ones, tick by tick."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from formation_swarm.protocol.messages import Command


@dataclass(frozen=True)
class Difference:
    """The first tick whose commands differ (``replayed`` None: the replay gave none)."""

    tick: int
    recorded: Command
    replayed: Command | None


@dataclass(frozen=True)
class Comparison:
    """``ticks`` compared (every tick with a recorded command), how many differ
    and the first that does; the RMS and the largest difference of each
    wheel's speed over the ticks both answered (m/s; None: no such tick)."""

    ticks: int
    differing: int
    first: Difference | None
    rms_left_mps: float | None
    rms_right_mps: float | None
    max_mps: float | None
    max_tick: int | None

    @property
    def identical(self) -> bool:
        return self.differing == 0


def compare(recorded: Mapping[int, Command], replayed: Mapping[int, Command]) -> Comparison:
    """Each recorded tick's command against the replay's, field by field (wheel
    speeds to the bit, formation, done, seq, sender)."""
    differing, first = 0, None
    sq_left = sq_right = 0.0
    both = 0
    max_mps, max_tick = None, None
    for tick in sorted(recorded):
        rec, rep = recorded[tick], replayed.get(tick)
        if rep != rec:
            differing += 1
            if first is None:
                first = Difference(tick, rec, rep)
        if rep is None:
            continue
        both += 1
        dl, dr = rep.left_mps - rec.left_mps, rep.right_mps - rec.right_mps
        sq_left += dl * dl
        sq_right += dr * dr
        worst = max(abs(dl), abs(dr))
        if max_mps is None or worst > max_mps:
            max_mps, max_tick = worst, tick
    return Comparison(
        ticks=len(recorded),
        differing=differing,
        first=first,
        rms_left_mps=math.sqrt(sq_left / both) if both else None,
        rms_right_mps=math.sqrt(sq_right / both) if both else None,
        max_mps=max_mps,
        max_tick=max_tick,
    )


def describe(cmd: Command | None) -> str:
    """A command in one line, its speeds to the bit (repr)."""
    if cmd is None:
        return "none"
    return (
        f"left {cmd.left_mps!r} m/s, right {cmd.right_mps!r} m/s, formation {cmd.formation}, "
        f"done {cmd.done}, seq {cmd.seq}"
    )
