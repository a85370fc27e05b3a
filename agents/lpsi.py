"""Baseline: the separation-bearing (l-psi) leader-follower controller.

Desai, Ostrowski and Kumar (the paper's reference [2]): the follower drives
a point at distance d ahead of its axle so that its distance l and bearing psi
from the reference robot's centre obey

    dl/dt = a1 (l_d - l),        dpsi/dt = a2 (psi_d - psi),

by input-output feedback linearisation. With gamma = theta_ref + psi - theta:

    A = a1 (l_d - l) + v_ref cos psi
    B = l (a2 (psi_d - psi) + w_ref) - v_ref sin psi
    v = A cos gamma - B sin gamma,     w = (A sin gamma + B cos gamma) / d

(the published form, rho = A / cos gamma, v = rho - d w tan gamma, is the
same solution divided through by cos gamma). psi is measured counter-clockwise
from the reference's heading to the vector from its centre to the follower's
point.

Everything here is in the follower frame (x right, y ahead), from the same
EKF state the fuzzy controller uses: the reference's centre, relative
heading, speed v_ref and turn rate w_ref. The desired point is the formation
target moved d ahead along the reference's heading, so that on a straight
line the follower's centre (not its point d) sits on the target, as the fuzzy
controller's does. Wheel speeds are clipped to +-max_wheel_mps (the fuzzy
controller's top speed, V_N max + a, by default): same actuators for both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from formation_swarm.agents.geometry import Point
from formation_swarm.common.checks import finite, positive
from formation_swarm.world.kinematics import wrap_angle


@dataclass(frozen=True)
class LpsiParams:
    l_gain: float = 1.0  # a1, 1/s
    psi_gain: float = 1.0  # a2, 1/s
    d_m: float = 0.25  # the controlled point, ahead of the axle
    max_wheel_mps: float = 2.5

    def __post_init__(self) -> None:
        positive("lpsi.l_gain", self.l_gain)
        positive("lpsi.psi_gain", self.psi_gain)
        positive("lpsi.d_m", self.d_m)
        positive("lpsi.max_wheel_mps", self.max_wheel_mps)


def control(
    ref: Point, phi_rad: float, v_ref_mps: float, w_ref_rps: float, *, offset: Point, width_m: float, p: LpsiParams
) -> tuple[float, float]:
    """(left, right) wheel speeds, m/s. ``ref``, ``phi_rad``: the reference's centre and
    heading in the follower frame; ``offset``: the slot in the reference's frame."""
    x_r, y_r = finite("ref.x_m", ref[0]), finite("ref.y_m", ref[1])
    phi = finite("phi_rad", phi_rad)
    v1, w1 = finite("v_ref_mps", v_ref_mps), finite("w_ref_rps", w_ref_rps)
    o_x, o_y = finite("offset.x_m", offset[0]), finite("offset.y_m", offset[1]) + p.d_m
    positive("width_m", width_m)
    # Angles are taken in the follower frame, where the follower heads along +y.
    theta_ref = math.pi / 2 + phi
    l_d = math.hypot(o_x, o_y)
    psi_d = math.atan2(o_y, o_x) - math.pi / 2  # the offset's bearing from the reference's heading
    r_x, r_y = -x_r, p.d_m - y_r  # reference centre -> our point
    sep = math.hypot(r_x, r_y)
    bearing = math.atan2(r_y, r_x)
    psi = wrap_angle(bearing - theta_ref)
    gamma = wrap_angle(bearing - math.pi / 2)
    a = p.l_gain * (l_d - sep) + v1 * math.cos(psi)
    b = sep * (p.psi_gain * wrap_angle(psi_d - psi) + w1) - v1 * math.sin(psi)
    v = a * math.cos(gamma) - b * math.sin(gamma)
    w = (a * math.sin(gamma) + b * math.cos(gamma)) / p.d_m
    lim = p.max_wheel_mps
    left = min(max(v - w * width_m / 2.0, -lim), lim)
    right = min(max(v + w * width_m / 2.0, -lim), lim)
    return left, right
