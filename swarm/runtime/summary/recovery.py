"""How the formation came back after a fault that ends: link, partition,
sensor and actuator faults, from the summary's ``error_windows`` (each
follower's mean and largest formation error per 1 s window).

Process faults get theirs from the world to the tick (world.recovery); these
faults leave no return to watch, so their figure is read off the windows
that start at or after the fault's end: the first whose mean error is below
the bound, and the largest error in the WINDOW_S after the end. It is as
fine as a window (1 s). The watched followers: the fault's robots among the
followers, or every follower when the fault touches the leader or all robots.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from formation_swarm.world.recovery import BOUND_M, WINDOW_S

if TYPE_CHECKING:
    from formation_swarm.common.faults import Fault
    from formation_swarm.spec.scenario import Scenario


def window_recoveries(f: Fault, sc: Scenario, windows: Mapping[str, Any] | None) -> list[dict[str, Any]]:
    """One record of the formation's return after ``f`` ends (none for a
    fault that lasts to the run's end, or a run without windows)."""
    end = f.end_tick(sc.dt_s)
    if end is None or not isinstance(windows, Mapping) or not isinstance(windows.get("window_s"), (int, float)):
        return []
    robots = f.robots
    followers = sc.follower_ids
    touches_leader = robots is None or sc.leader.robot_id in robots
    watched = list(followers) if touches_leader else [r for r in followers if r in robots]
    means = _worst(windows.get("mean_m"), watched)
    if not means:
        return []
    width = float(windows["window_s"])
    since_s = end * sc.dt_s
    first = math.ceil(since_s / width - 1e-9)  # the first window wholly after the end
    if first >= len(means):
        return []  # the run ended with the fault, or within a window of its end
    below = next((k for k in range(first, len(means)) if means[k] < BOUND_M), None)
    window = range(first, min(len(means), first + math.ceil(WINDOW_S / width)))
    peaks = _worst(windows.get("max_m"), watched)
    return [
        {
            "event": "fault over",
            "fault": str(f),
            "since_tick": end,
            "since_s": since_s,
            "watched": watched,
            "bound_m": BOUND_M,
            "resolution_s": width,
            "first_below_after_s": None if below is None else (below + 1) * width - since_s,
            "window_s": WINDOW_S,
            "max_in_window_m": max((peaks[k] for k in window if k < len(peaks)), default=None),
        }
    ]


def _worst(per_robot: Any, watched: list[int]) -> list[float]:
    """Per window, the largest of the watched followers' values (a follower
    whose windows end early counts until then)."""
    if not isinstance(per_robot, Mapping):
        return []
    rows = [per_robot[str(r)] for r in watched if isinstance(per_robot.get(str(r)), list)]
    n = max((len(row) for row in rows), default=0)
    return [max(row[k] for row in rows if k < len(row)) for k in range(n)]
