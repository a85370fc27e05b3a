"""The leader's scripted path: waypoints followed at a cruise speed.

Pure pursuit: steer toward the point ``lookahead_m`` ahead on the polyline,
turning at most at ``max_turn_rate_rps``; wheel speeds follow from eq. 8-9.
The leader knows its own pose (odometry, given by the world).

The pilot moves on to the next segment when the current one's end is within
the look-ahead or when the robot has passed it (its projection on the
segment lies beyond the end). Pursuit of a point 1 m ahead turns late, at the
look-ahead, and a robot whose turn radius R = speed / turn rate is much
larger than that overshoots the corner by about R and can then circle a goal
that lies inside its turning circle for ever (on the paper's path: from 1.6
m/s at 0.25 rad/s, 1.25 m/s at 0.2 rad/s). So once the robot has turned half
a circle on one segment, the pilot steers for the rest of the path at the
point 2 R + ``lookahead_m`` ahead, which no turning circle (diameter 2 R)
can contain, and ends the path when it passes the last waypoint. Where the
pursuit finishes without that, it turns less on one segment (measured on the
paper's path: at most 154 deg in the 27 of 48 cases of tests/unit/agents/test_pilot.py
that do, 150 deg in the shipped scenarios), so those runs are unchanged
(docs/paper.md, "The leader's path").

With ``corners = "arcs"`` the pilot flies each corner on a circle of radius
R tangent to both segments instead (:func:`round_corners`), starting the turn
R tan(theta / 2) before the corner: no overshoot. :func:`turn_room` says
whether the segments are long enough for that.

On its first step the pilot starts from the segment nearest its pose (the
first of equally near ones): the first segment for a leader at the path's
start, where it is along the path for a leader restarted mid-run, which must
not drive back to the start.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

from formation_swarm.common.checks import positive, vector
from formation_swarm.world.kinematics import Pose, to_body_frame, wrap_angle

CORNERS = ("pursuit", "arcs")


@dataclass
class PathPilot:
    waypoints: Sequence[Sequence[float]]
    speed_mps: float
    width_m: float
    lookahead_m: float = 1.0
    max_turn_rate_rps: float = 1.0
    loop: bool = False
    corners: str = "pursuit"  # or "arcs": each corner flown on a circle of radius speed / turn rate
    _pts: list[tuple[float, float]] = field(init=False, repr=False)
    _seg: int = field(init=False, default=0)
    _placed: bool = field(init=False, default=False)  # the first step found the nearest segment
    finished: bool = field(init=False, default=False)
    wide: bool = field(init=False, default=False)  # steering at 2 R + lookahead_m ahead
    _turned_rad: float = field(init=False, default=0.0)  # heading change since the segment began
    _heading_rad: float | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        if len(self.waypoints) < 2:
            raise ValueError(f"waypoints must hold at least 2 points, got {len(self.waypoints)}")
        self._pts = [vector(f"waypoints[{i}]", p, 2) for i, p in enumerate(self.waypoints)]  # type: ignore[misc]
        positive("speed_mps", self.speed_mps)
        positive("width_m", self.width_m)
        positive("lookahead_m", self.lookahead_m)
        positive("max_turn_rate_rps", self.max_turn_rate_rps)
        self._radius_m = self.speed_mps / self.max_turn_rate_rps
        if self.corners not in CORNERS:
            raise ValueError(f"corners must be one of {', '.join(map(repr, CORNERS))}, got {self.corners!r}")
        if self.corners == "arcs":
            if problems := turn_room(self._pts, self._radius_m):
                raise ValueError("corners = 'arcs': " + "; ".join(problems))
            self._pts = round_corners(self._pts, self._radius_m)

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

    def _passed(self, i: int, x: float, y: float) -> bool:
        """Whether (x, y) projects past the end of segment i."""
        (ax, ay), (ex, ey) = self._pts[i], self._pts[i + 1]
        return (x - ex) * (ex - ax) + (y - ey) * (ey - ay) > 0.0

    def _goal(self, x: float, y: float) -> tuple[float, float]:
        pts = self._pts
        # Advance past segments whose end is within the look-ahead or behind the robot.
        while self._seg < len(pts) - 2:
            ex, ey = pts[self._seg + 1]
            if math.hypot(ex - x, ey - y) > self.lookahead_m and not self._passed(self._seg, x, y):
                break
            self._seg += 1
            self._turned_rad = 0.0
        (ax, ay), (bx, by) = pts[self._seg], pts[self._seg + 1]
        dx, dy = bx - ax, by - ay
        seg_len2 = dx * dx + dy * dy
        t = 0.0 if seg_len2 == 0.0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy) / seg_len2))
        seg_len = math.sqrt(seg_len2)
        if self.wide:
            return self._along(self._seg, t * seg_len + 2.0 * self._radius_m + self.lookahead_m)
        t_goal = min(1.0, t + (self.lookahead_m / seg_len if seg_len > 0 else 1.0))
        return ax + t_goal * dx, ay + t_goal * dy

    def _along(self, seg: int, s_m: float) -> tuple[float, float]:
        """The point s_m along the path from the start of segment seg, on past the end."""
        pts = self._pts
        while True:
            (ax, ay), (bx, by) = pts[seg], pts[seg + 1]
            seg_len = math.hypot(bx - ax, by - ay)
            if s_m <= seg_len or seg == len(pts) - 2:
                f = s_m / seg_len if seg_len > 0.0 else 0.0
                return ax + f * (bx - ax), ay + f * (by - ay)
            s_m -= seg_len
            seg += 1

    def step(self, pose: Pose) -> tuple[float, float]:
        """Wheel speeds (left, right) in m/s for this tick; (0, 0) once at the end."""
        if self.finished:
            return 0.0, 0.0
        if not self._placed:
            self._seg, self._placed = self.nearest_segment(pose[0], pose[1]), True
        if self._heading_rad is not None:
            self._turned_rad += wrap_angle(pose[2] - self._heading_rad)
            if abs(self._turned_rad) > math.pi:
                self.wide = True  # half a turn on one segment: circling a goal it cannot reach
        self._heading_rad = pose[2]
        end = self._pts[-1]
        if self._seg >= len(self._pts) - 2 and (
            math.hypot(end[0] - pose[0], end[1] - pose[1]) < 0.5 * self.lookahead_m
            or (self.wide and self._passed(self._seg, pose[0], pose[1]))
        ):
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


def round_corners(
    waypoints: Sequence[Sequence[float]], radius_m: float, step_m: float = 0.25
) -> list[tuple[float, float]]:
    """The waypoints with each corner replaced by an arc of radius ``radius_m``
    tangent to both its segments, as points at most ``step_m`` apart on the arc.

    The arc starts and ends R tan(theta / 2) from the corner (theta: the turn);
    :func:`turn_room` says whether the segments hold that. Zero-length
    segments are dropped.
    """
    pts = [(float(p[0]), float(p[1])) for p in waypoints]
    pts = [p for i, p in enumerate(pts) if i == 0 or p != pts[i - 1]]
    out = [pts[0]]
    for a, c, b in zip(pts[:-2], pts[1:-1], pts[2:], strict=True):
        h0 = math.atan2(c[1] - a[1], c[0] - a[0])
        turn = wrap_angle(math.atan2(b[1] - c[1], b[0] - c[0]) - h0)  # CCW positive
        if turn == 0.0:
            out.append(c)
            continue
        tangent = radius_m * math.tan(0.5 * abs(turn))
        sx, sy = c[0] - tangent * math.cos(h0), c[1] - tangent * math.sin(h0)
        side = 1.0 if turn > 0.0 else -1.0  # the centre is left of the robot on a left turn
        cx, cy = sx - side * radius_m * math.sin(h0), sy + side * radius_m * math.cos(h0)
        n = max(1, math.ceil(radius_m * abs(turn) / step_m))
        for k in range(n + 1):
            h = h0 + turn * k / n
            out.append((cx + side * radius_m * math.sin(h), cy - side * radius_m * math.cos(h)))
    out.append(pts[-1])
    return out


class NoRoom(NamedTuple):
    """Where a robot turning on circles cannot fly a path (``no_room``): a
    segment from ``start`` to ``end``, ``length_m`` long, shorter than its
    corners take (``need_m``), or, with ``need_m`` infinite, a reversal at ``end``."""

    start: tuple[float, float]
    end: tuple[float, float]
    length_m: float
    need_m: float


def no_room(waypoints: Sequence[Sequence[float]], radius_m: float) -> list[NoRoom]:
    """Why a robot turning on circles of ``radius_m`` cannot fly these waypoints.

    A corner that turns the path by theta, flown on a circle of radius R
    tangent to both segments, starts and ends R tan(theta / 2) from the
    corner. Each segment must hold what its two corners take from it (the
    first and the last segment, one corner each); a reversal (theta = 180
    deg) fits no circle. Empty when every corner fits. Zero-length segments
    are skipped. The reversals first, then the segments, in path order.
    """
    pts = [(float(p[0]), float(p[1])) for p in waypoints]
    segs = [(a, b) for a, b in zip(pts[:-1], pts[1:], strict=True) if a != b]
    lengths = [math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in segs]
    heads = [math.atan2(b[1] - a[1], b[0] - a[0]) for a, b in segs]
    turns = [abs(wrap_angle(h1 - h0)) for h0, h1 in zip(heads[:-1], heads[1:], strict=True)]
    problems = []
    take = []
    for i, theta in enumerate(turns):
        if theta >= math.pi - 1e-9:
            problems.append(NoRoom(*segs[i], lengths[i], math.inf))
            take.append(math.inf)
        else:
            take.append(radius_m * math.tan(0.5 * theta))
    for j, length in enumerate(lengths):
        need = (take[j - 1] if j >= 1 else 0.0) + (take[j] if j < len(take) else 0.0)
        if need > length + 1e-9 and math.isfinite(need):
            problems.append(NoRoom(*segs[j], length, need))
    return problems


def turn_room(waypoints: Sequence[Sequence[float]], radius_m: float) -> list[str]:
    """``no_room`` in words, one line per place."""
    return [
        f"the path reverses at {p.end}: no turn circle fits a 180 deg turn"
        if math.isinf(p.need_m)
        else f"segment {p.start} -> {p.end} is {p.length_m:.4g} m long, its corners take {p.need_m:.4g} m"
        f" (R tan(theta / 2) per corner, R = {radius_m:.4g} m)"
        for p in no_room(waypoints, radius_m)
    ]
