"""The follower's control law, with no ROS in it: a point held behind a robot.

    pursue(own, ref, ref_twist, slot) -> (linear_x_mps, angular_z_rps)
    answer(poses, twists, formation, robot=3, slots=FIG11) -> (linear_x_mps, angular_z_rps)

``own`` and ``ref`` are poses (x m, y m, yaw rad) in the map frame, as
nav_msgs/Odometry gives them; ``ref_twist`` is the reference robot's
(forward speed m/s, turn rate rad/s), its Odometry's twist. The target is the
point ``slot.back_m`` behind and ``slot.right_m`` to the right of the
reference. A point ``slot.lookahead_m`` ahead of the follower tracks it: its
velocity is the target's own plus ``slot.gain_per_s`` times the gap, turned
into a forward speed and a turn rate (feedback linearisation of the
unicycle). The answer is a geometry_msgs/Twist's linear.x and angular.z.

``answer`` picks the reference and the slot by the formation code flown
(/formation). In fig11 robot 2 leads robot 3: robot 3 holds the point 3 m
to robot 2's right in the triangle (code 0), and 1.5 m behind it in the
line (code 1), which takes it between the obstacles. Before the poses it
needs have come, it answers (0, 0).

follower.py (rclpy), without_ros.py (no ROS) and the tests' clients call ``answer``.
"""

from __future__ import annotations

import math
from typing import NamedTuple


class Pose(NamedTuple):
    x_m: float
    y_m: float
    yaw_rad: float


class Slot(NamedTuple):
    """Where to hold: ``back_m`` behind and ``right_m`` right of the reference;
    the law's lookahead (m), gain (1/s) and limits (m/s, rad/s)."""

    back_m: float = 1.5
    right_m: float = 1.5
    lookahead_m: float = 0.3
    gain_per_s: float = 1.5
    max_speed_mps: float = 2.5
    max_turn_rps: float = 3.0


# fig11's formations, by code: robot 3's reference robot and its slot there.
FIG11 = {0: (2, Slot(back_m=0.0, right_m=3.0)), 1: (2, Slot(back_m=1.5, right_m=0.0))}


def target(ref: Pose, slot: Slot) -> tuple[float, float]:
    """The point held: ``back_m`` behind and ``right_m`` right of ``ref``, map frame."""
    c, s = math.cos(ref.yaw_rad), math.sin(ref.yaw_rad)
    # Behind: minus the heading (c, s); right: minus the left normal (-s, c).
    return ref.x_m - slot.back_m * c + slot.right_m * s, ref.y_m - slot.back_m * s - slot.right_m * c


def pursue(own: Pose, ref: Pose, ref_twist: tuple[float, float], slot: Slot) -> tuple[float, float]:
    """The Twist (forward speed m/s, turn rate rad/s) that brings ``own`` to its slot."""
    for name, value in (*zip(("own", "ref"), (own, ref), strict=True), ("ref_twist", ref_twist)):
        if not all(math.isfinite(v) for v in value):
            raise ValueError(f"{name} must be finite numbers, got {value!r}")
    tx, ty = target(ref, slot)
    # The target moves with the reference: v along its heading plus w x (target - ref).
    v_ref, w_ref = ref_twist
    c, s = math.cos(ref.yaw_rad), math.sin(ref.yaw_rad)
    vx = v_ref * c - w_ref * (ty - ref.y_m)
    vy = v_ref * s + w_ref * (tx - ref.x_m)
    oc, os_ = math.cos(own.yaw_rad), math.sin(own.yaw_rad)
    px, py = own.x_m + slot.lookahead_m * oc, own.y_m + slot.lookahead_m * os_
    ux = vx + slot.gain_per_s * (tx - px)
    uy = vy + slot.gain_per_s * (ty - py)
    speed = ux * oc + uy * os_
    turn = (-ux * os_ + uy * oc) / slot.lookahead_m
    return _clamp(speed, slot.max_speed_mps), _clamp(turn, slot.max_turn_rps)


def _clamp(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))


def answer(
    poses: dict[int, Pose],
    twists: dict[int, tuple[float, float]],
    formation: int,
    robot: int = 3,
    slots: dict[int, tuple[int, Slot]] = FIG11,
) -> tuple[float, float]:
    """Robot ``robot``'s Twist for the formation ``formation`` (a code unknown
    to ``slots``: the first one's), from the robots' poses and twists."""
    ref, slot = slots.get(formation, next(iter(slots.values())))
    if robot not in poses or ref not in poses:
        return 0.0, 0.0
    return pursue(poses[robot], poses[ref], twists.get(ref, (0.0, 0.0)), slot)
