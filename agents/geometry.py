"""Formation geometry in the follower frame, paper eq. 1-6 and eq. 11-12.

Follower frame: the follower at the origin, y ahead, x to its right (paper
section 2.1: x_l = rho sin beta, y_l = rho cos beta). Angles CCW positive,
so R_z(phi) (eq. 3) turns a leader-frame vector into the follower frame
when the leader is rotated phi to the left of the follower.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from formation_swarm.common.checks import finite, non_negative


class Point(NamedTuple):
    x_m: float
    y_m: float


@dataclass(frozen=True, kw_only=True, slots=True)
class MarkerReading:
    """A camera's reading of a reference's marker (paper eq. 1)."""

    rho_m: float  # distance to the marker
    phi_rad: float  # the reference's heading relative to ours, counter-clockwise
    beta_rad: float  # bearing of the marker, positive to the right


class TargetErrors(NamedTuple):
    """The fuzzy controller's inputs (eq. 4-6)."""

    alpha_rad: float
    rho_m: float
    drho_m: float


def rotate(phi_rad: float, x: float, y: float) -> Point:
    """R_z(phi) of eq. 3 applied to the planar vector (x, y)."""
    c = math.cos(phi_rad)
    s = math.sin(phi_rad)
    return Point(c * x - s * y, s * x + c * y)


def marker_point(rho_m: float, beta_rad: float) -> Point:
    """The marker P_l in the follower frame: x_l = rho sin beta, y_l = rho cos beta."""
    rho = non_negative("rho_m", rho_m)
    beta = finite("beta_rad", beta_rad)
    return Point(rho * math.sin(beta), rho * math.cos(beta))


def leader_point(rho_m: float, phi_rad: float, beta_rad: float, marker_offset_m: float) -> Point:
    """Eq. 1: the leader's centre P_r in the follower frame.

    The marker sits ``marker_offset_m`` (d) behind the leader's centre along
    the leader's axis, so P_r = P_l + R_z(phi) [0, d]. The paper prints
    P_r = R_z(phi) [x_l, y_l + d]; that form agrees with ours only for phi = 0
    (docs/paper.md, eq. 1).
    """
    phi = finite("phi_rad", phi_rad)
    d = non_negative("marker_offset_m", marker_offset_m)
    pl = marker_point(rho_m, beta_rad)
    off = rotate(phi, 0.0, d)
    return Point(pl.x_m + off.x_m, pl.y_m + off.y_m)


def target_point(leader: Point, phi_rad: float, offset: Point) -> Point:
    """Eq. 2: virtual target P_g = P_r + R_z(phi) P_vt (P_vt in the leader frame)."""
    off = rotate(phi_rad, offset[0], offset[1])
    return Point(leader[0] + off.x_m, leader[1] + off.y_m)


def target_from_reading(rho_m: float, phi_rad: float, beta_rad: float, marker_offset_m: float, offset: Point) -> Point:
    """Eq. 1 then eq. 2: the measured virtual target from one marker reading."""
    pr = leader_point(rho_m, phi_rad, beta_rad, marker_offset_m)
    return target_point(pr, phi_rad, offset)


def errors(target: Point, prev_rho_m: float | None, phi_rad: float = 0.0) -> TargetErrors:
    """Eq. 4-6: heading error alpha, distance error rho and its change.

    alpha = atan2(x_g, y_g) (eq. 4), positive when the target is to the
    follower's right. rho (eq. 5) is the follower-to-target distance |P_g|,
    signed: negative when the follower is ahead of its target along the
    reference robot's heading (``phi_rad``, as in eq. 11-12), i.e. when the
    target is still to come. The printed "-(lambda_g + y_g)" is garbled; we
    keep its sign and its y (docs/paper.md, eq. 5). A negative rho is "Close"
    for FIS-1: a follower, which cannot reverse, slows down and lets its target
    come instead of looping back to it. drho = rho_t - rho_{t-1} (eq. 6), 0
    on the first tick.
    """
    xg = finite("target.x_m", target[0])
    yg = finite("target.y_m", target[1])
    phi = finite("phi_rad", phi_rad)
    along = -xg * math.sin(phi) + yg * math.cos(phi)  # P_g . R(phi)[0, 1]
    rho = math.copysign(math.hypot(xg, yg), along)
    drho = 0.0 if prev_rho_m is None else rho - finite("prev_rho_m", prev_rho_m)
    return TargetErrors(math.atan2(xg, yg), rho, drho)


def lookahead_bearing(target: Point, phi_rad: float, lookahead_m: float) -> float:
    """The bearing (as alpha, eq. 4: positive to the right) of the point
    ``lookahead_m`` ahead of ``target`` along the reference's heading
    (``phi_rad``, the direction R(phi)[0, 1] of eq. 5's sign); 0 m gives alpha.

    Not the paper's (docs/paper.md, "The steering look-ahead"). Steering at
    the target itself, a follower that trails it by rho turns by about
    e / rho for a sideways error e of the target. A target d behind its
    reference moves sideways by d per radian the reference turns: 1.5 m
    behind it, with the follower 0.35 m behind the target, the follower turns
    about four times as far as its reference swings, and the swings grow
    down every chain. Aimed ``lookahead_m`` farther along the reference's
    course, it turns by about e / (rho + lookahead_m).
    """
    lookahead = non_negative("lookahead_m", lookahead_m)
    phi = finite("phi_rad", phi_rad)
    return math.atan2(target[0] - lookahead * math.sin(phi), target[1] + lookahead * math.cos(phi))


def follower_in_leader_frame(leader: Point, phi_rad: float) -> Point:
    """Eq. 11-12: the follower's position P_xy seen from the leader's frame.

    P_x = -x_r cos phi - y_r sin phi, P_y = x_r sin phi - y_r cos phi (the
    paper prints both as P_x; the second is P_y).
    """
    c = math.cos(phi_rad)
    s = math.sin(phi_rad)
    return Point(-leader[0] * c - leader[1] * s, leader[0] * s - leader[1] * c)
