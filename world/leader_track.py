"""How far the leader strays from its path, from the true poses: its largest
distance from the waypoints' polyline over the run, and its distance from the
last waypoint where the run ends. Its pilot overshoots a corner by about
speed / turn rate; at a speed its corners do not fit it steers wide
(docs/paper.md, "The leader's path"), which these two figures show.
"""

from __future__ import annotations

import math
from collections.abc import Sequence


def distance_to_segment(x: float, y: float, a: Sequence[float], b: Sequence[float]) -> float:
    """The distance from (x, y) to the segment a-b, m."""
    ax, ay = float(a[0]), float(a[1])
    dx, dy = float(b[0]) - ax, float(b[1]) - ay
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0.0 else min(1.0, max(0.0, ((x - ax) * dx + (y - ay) * dy) / length2))
    return math.hypot(x - ax - t * dx, y - ay - t * dy)


class LeaderTrack:
    """The leader's distance from its path, fed one true position per tick."""

    def __init__(self, waypoints: Sequence[Sequence[float]]) -> None:
        self.waypoints = [(float(p[0]), float(p[1])) for p in waypoints]
        self.max_off_path_m = 0.0

    def off_path_m(self, x: float, y: float) -> float:
        """The distance from (x, y) to the nearest point of the waypoints' polyline, m."""
        pts = self.waypoints
        return min(distance_to_segment(x, y, a, b) for a, b in zip(pts, pts[1:], strict=False))

    def add(self, x: float, y: float) -> None:
        self.max_off_path_m = max(self.max_off_path_m, self.off_path_m(x, y))

    def as_dict(self, end: Sequence[float]) -> dict[str, float]:
        """The figures, with the leader's position ``end`` where the run ends."""
        last = self.waypoints[-1]
        x, y = float(end[0]), float(end[1])
        return {
            "max_off_path_m": max(self.max_off_path_m, self.off_path_m(x, y)),
            "end_from_last_waypoint_m": math.hypot(x - last[0], y - last[1]),
        }
