"""Differential-drive kinematics, paper eq. 7-10.

Conventions (docs/paper.md, "Frames and signs"): world frame right-handed,
x east, y north, heading theta counter-clockwise from +x, in rad. A faster
left wheel turns the robot right (clockwise), so omega = (v_R - v_L) / L;
the paper prints (v_L - v_R) / L because it measures heading clockwise.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from formation_swarm.common.checks import finite, positive


class Pose(NamedTuple):
    x_m: float
    y_m: float
    theta_rad: float


def wrap_angle(angle_rad: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def body_twist(v_left_mps: float, v_right_mps: float, width_m: float) -> tuple[float, float]:
    """Wheel speeds -> (v, omega): eq. 8 and eq. 9 (CCW-positive omega)."""
    return 0.5 * (v_left_mps + v_right_mps), (v_right_mps - v_left_mps) / width_m


def step(pose: Pose, v_left_mps: float, v_right_mps: float, width_m: float, dt_s: float) -> Pose:
    """Advance one robot by ``dt_s`` with constant wheel speeds.

    Integrates eq. 7 (equivalently eq. 10) exactly: the robot moves on a
    circular arc of radius v/omega, or a straight segment when omega = 0.
    """
    x = finite("pose.x_m", pose[0])
    y = finite("pose.y_m", pose[1])
    th = finite("pose.theta_rad", pose[2])
    vl = finite("v_left_mps", v_left_mps)
    vr = finite("v_right_mps", v_right_mps)
    width = positive("width_m", width_m)
    dt = positive("dt_s", dt_s)
    return _step_unchecked(x, y, th, vl, vr, width=width, dt=dt)


# Module constants and functions bound once: the step runs for every robot on every tick.
_PI = math.pi
_TWO_PI = 2.0 * math.pi
_cos, _sin = math.cos, math.sin
_pose = tuple.__new__  # what Pose(x, y, theta) does, without its Python frame


def _step_unchecked(x: float, y: float, th: float, vl: float, vr: float, *, width: float, dt: float) -> Pose:
    # body_twist and wrap_angle written out: the same operations in the same order.
    v = 0.5 * (vl + vr)
    w = (vr - vl) / width
    dth = w * dt
    if abs(dth) < 1e-9:
        # Second-order expansion of the arc: exact to ~1e-18 m per metre here.
        mid = th + 0.5 * dth
        return _pose(Pose, (x + v * dt * _cos(mid), y + v * dt * _sin(mid), (th + dth + _PI) % _TWO_PI - _PI))
    radius = v / w
    th1 = th + dth
    return _pose(
        Pose, (x + radius * (_sin(th1) - _sin(th)), y - radius * (_cos(th1) - _cos(th)), (th1 + _PI) % _TWO_PI - _PI)
    )


def to_body_frame(observer: Pose, x_m: float, y_m: float) -> tuple[float, float]:
    """World point -> the observer's robot frame (x to its right, y ahead).

    This is the follower frame of paper section 2.1 (x_l = rho sin beta,
    y_l = rho cos beta).
    """
    dx = x_m - observer[0]
    dy = y_m - observer[1]
    c = math.cos(observer[2])
    s = math.sin(observer[2])
    return dx * s - dy * c, dx * c + dy * s


def from_body_frame(observer: Pose, x_b: float, y_b: float) -> tuple[float, float]:
    """Inverse of :func:`to_body_frame`."""
    c = math.cos(observer[2])
    s = math.sin(observer[2])
    return observer[0] + x_b * s + y_b * c, observer[1] - x_b * c + y_b * s
