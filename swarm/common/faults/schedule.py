"""A fault schedule against the run it is for: what cannot apply to the run
(an error before any process starts) and what the run's end cuts short (a
warning).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from formation_swarm.common.checks import MAX_TICKS, tick_limit
from formation_swarm.common.faults.kinds import LINK, PROCESS, SENSOR

if TYPE_CHECKING:
    from formation_swarm.common.faults import Fault

MAX_FAULTS = 256


def check_against(
    faults: Sequence[Fault], robots: Sequence[int], leader_id: int, duration_s: float, dt_s: float
) -> None:
    """Faults that cannot apply to this run: unknown robots, a start past the end,
    a formation link to the leader, a camera fault on the leader (it has none),
    two process faults on one process at once."""
    if len(faults) > MAX_FAULTS:
        raise ValueError(f"at most {MAX_FAULTS} faults, got {len(faults)}")
    known = set(robots)
    busy: dict[str, list[tuple[int, int | None, Fault]]] = {}
    for f in faults:
        where = f"fault '{f}'"
        _check_times(f, where, duration_s, dt_s)
        named = f.robots
        if named is not None and (unknown := sorted(set(named) - known)):
            raise ValueError(
                f"{where}: no robot {', '.join(map(str, unknown))} in this run; robots are "
                f"{', '.join(map(str, robots))}"
            )
        if (
            f.group == LINK
            and "formation" in f.link_classes
            and named is not None
            and leader_id in named
            and f.link_classes == ("formation",)
        ):
            raise ValueError(f"{where}: robot {leader_id} is the leader; formation links go to followers")
        if f.group == SENSOR and named is not None and leader_id in named:
            raise ValueError(
                f"{where}: robot {leader_id} is the leader; it has no camera in this model (sensor faults apply "
                "to followers; '*' names them all)"
            )
        if f.kind == "partition" and f.param("from") == "leader" and named is not None and leader_id in named:
            raise ValueError(f"{where}: robot {leader_id} is the leader; it cannot be cut off from itself")
        if f.group == PROCESS:
            start, end = f.start_tick(dt_s), f.end_tick(dt_s)
            for s2, e2, other in busy.get(f.target, []):
                # A kill lasts to the end of the run; the others until they end.
                if (e2 is None or start < e2) and (end is None or s2 < end):
                    raise ValueError(f"{where} overlaps '{other}' on the same process")
            busy.setdefault(f.target, []).append((start, end, f))


def _check_times(f: Fault, where: str, duration_s: float, dt_s: float) -> None:
    """A start before the run's end; a length (for, a restart's after) of ticks a run can count."""
    ticks = int(round(duration_s / dt_s))  # ticks 0 .. ticks - 1 are run
    # A start a tick or more past the end is past it without a tick count made (1e308 s has none).
    if f.at_s >= duration_s + dt_s or f.start_tick(dt_s) >= ticks:
        last = (ticks - 1) * dt_s
        raise ValueError(
            f"{where}: starts at {f.at_s:g} s, at or after the run's end ({duration_s:g} s; its "
            f"last tick is at {last:g} s)"
        )
    for name, length in (("for", f.for_s), ("after", f.param("after") if f.kind == "restart" else None)):
        # A length past the end is cut there (past_the_end), but its ticks are counted.
        if length is not None and length / dt_s > MAX_TICKS:
            raise ValueError(f"{where}: {name} must be at most {tick_limit(dt_s)}, got {length:g} s")


def past_the_end(faults: Sequence[Fault], duration_s: float, dt_s: float) -> list[str]:
    """Warnings for faults whose window reaches past the run's last tick: they
    are cut there, which a schedule written for a longer run may not mean."""
    ticks = int(round(duration_s / dt_s))
    out = []
    for f in faults:
        end = f.end_tick(dt_s)
        if f.for_s is not None and end is not None and end > ticks:
            kept = (ticks - f.start_tick(dt_s)) * dt_s
            out.append(f"fault '{f}' lasts past the run's end ({duration_s:g} s): it is cut there, after {kept:g} s")
    return out
