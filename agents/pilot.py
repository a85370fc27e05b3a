"""The leader's scripted path: waypoints followed at a cruise speed.

Pure pursuit: steer toward the point ``lookahead_m`` ahead on the polyline,
turning at most at ``max_turn_rate_rps``; wheel speeds follow from eq. 8-9.
The leader knows its own pose (odometry, given by the world).

On its first step the pilot starts from the segment nearest its pose (the
first of equally near ones): the first segment for a leader at the path's
start, where it is along the path for a leader restarted mid-run, which must
not drive back to the start.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from formation_swarm.checks import positive, vector
from formation_swarm.world.kinematics import Pose, to_body_frame


@dataclass
class PathPilot:
    waypoints: Sequence[Sequence[float]]
    speed_mps: float
    width_m: float
    lookahead_m: float = 1.0
    max_turn_rate_rps: float = 1.0
    loop: bool = False
    _pts: list[tuple[float, float]] = field(init=False, repr=False)
    _seg: int = field(init=False, default=0)
    _placed: bool = field(init=False, default=False)  # the first step found the nearest segment
    finished: bool = field(init=False, default=False)

    def __post_init__(self) -> None:
        if len(self.waypoints) < 2:
            raise ValueError(f"waypoints must hold at least 2 points, got {len(self.waypoints)}")
        self._pts = [vector(f"waypoints[{i}]", p, 2) for i, p in enumerate(self.waypoints)]  # type: ignore[misc]
        positive("speed_mps", self.speed_mps)
        positive("width_m", self.width_m)
        positive("lookahead_m", self.lookahead_m)
        positive("max_turn_rate_rps", self.max_turn_rate_rps)

    def nearest_segment(self, x: float, y: float) -> int:
        """The index of the segment nearest (x, y); the first of equally near ones."""
        best, best_d2 = 0, math.inf
        for i, ((ax, ay), (bx, by)) in enumerate(zip(self._pts[:-1], self._pts[1:], strict=True)):
            dx, dy = bx - ax, by - ay
            seg_len2 = dx * dx + dy * dy
            t = 0.0 if seg_len2 == 0.0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy) / seg_len2))
            d2 = (ax + t * dx - x) ** 2 + (ay + t * dy - y) ** 2
            if d2 < best_d2:
                best, best_d2 = i, d2
        return best

    def _goal(self, x: float, y: float) -> tuple[float, float]:
        pts = self._pts
        # Advance past segments whose end is already within the look-ahead.
        while self._seg < len(pts) - 2:
            ex, ey = pts[self._seg + 1]
            if math.hypot(ex - x, ey - y) > self.lookahead_m:
                break
            self._seg += 1
        (ax, ay), (bx, by) = pts[self._seg], pts[self._seg + 1]
        dx, dy = bx - ax, by - ay
        seg_len2 = dx * dx + dy * dy
        t = 0.0 if seg_len2 == 0.0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy) / seg_len2))
        seg_len = math.sqrt(seg_len2)
        t_goal = min(1.0, t + (self.lookahead_m / seg_len if seg_len > 0 else 1.0))
        return ax + t_goal * dx, ay + t_goal * dy

    def step(self, pose: Pose) -> tuple[float, float]:
        """Wheel speeds (left, right) in m/s for this tick; (0, 0) once at the end."""
        if self.finished:
            return 0.0, 0.0
        if not self._placed:
            self._seg, self._placed = self.nearest_segment(pose[0], pose[1]), True
        end = self._pts[-1]
        if self._seg >= len(self._pts) - 2 and math.hypot(end[0] - pose[0], end[1] - pose[1]) < 0.5 * self.lookahead_m:
            self.finished = True
            return 0.0, 0.0
        gx, gy = self._goal(pose[0], pose[1])
        xb, yb = to_body_frame(pose, gx, gy)
        dist2 = xb * xb + yb * yb
        # Pure-pursuit curvature, CCW positive (xb is to the right).
        curvature = -2.0 * xb / dist2 if dist2 > 1e-12 else 0.0
        omega = max(-self.max_turn_rate_rps, min(self.max_turn_rate_rps, self.speed_mps * curvature))
        half = 0.5 * omega * self.width_m
        return self.speed_mps - half, self.speed_mps + half
