"""Partition-zone collision avoidance during a formation change, eq. 11-13.

The follower's position in its reference robot's frame (eq. 11-12, see
:func:`agents.geometry.follower_in_leader_frame`) puts it in one of three
zones: I ahead-right (P_x > 0, P_y > 0), II ahead-left (P_x < 0, P_y > 0),
III behind (P_y <= 0). Eq. 13 then picks the target:

- zone I: T1, beside the reference on its right, P_vt = [c, 0];
- zone II: T2, beside it on its left, P_vt = [-c, 0];
- zone III: the formation's own target T0 if it is nearer to the follower
  than T3 (behind the reference, P_vt = [0, -c]), else T3.

"T0 > T3" in eq. 13 is read as a comparison of distances from the follower
(docs/paper.md, eq. 13). ``c`` is the clearance the scenario gives; the paper
reuses the formation offsets' components, which are 0 in a line formation.
A zone boundary (P_x = 0 or P_y = 0) goes to the zone the paper's strict
inequalities leave: P_y = 0 is zone III, P_x = 0 with P_y > 0 is zone II.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import NamedTuple

from formation_swarm.agents.geometry import Point, follower_in_leader_frame, target_point
from formation_swarm.common.checks import finite, positive


class Zone(IntEnum):
    I = 1  # noqa: E741 - the paper names the zones I, II, III
    II = 2
    III = 3


class Choice(IntEnum):
    T0 = 0
    T1 = 1
    T2 = 2
    T3 = 3


class Selection(NamedTuple):
    zone: Zone
    choice: Choice
    target: Point


def zone_of(leader: Point, phi_rad: float) -> Zone:
    """The follower's zone around its reference robot (eq. 11-12)."""
    px, py = follower_in_leader_frame(leader, phi_rad)
    if py > 0.0:
        return Zone.I if px > 0.0 else Zone.II
    return Zone.III


def select_target(leader: Point, phi_rad: float, offset: Point, clearance_m: float) -> Selection:
    """Eq. 13: the target to steer to while the formation changes.

    ``leader`` and ``phi_rad`` are the reference robot's centre and
    orientation in the follower frame; ``offset`` is the new formation's P_vt.
    """
    finite("leader.x_m", leader[0])
    finite("leader.y_m", leader[1])
    phi = finite("phi_rad", phi_rad)
    c = positive("clearance_m", clearance_m)
    zone = zone_of(leader, phi)
    if zone is Zone.I:
        return Selection(zone, Choice.T1, target_point(leader, phi, Point(c, 0.0)))
    if zone is Zone.II:
        return Selection(zone, Choice.T2, target_point(leader, phi, Point(-c, 0.0)))
    t0 = target_point(leader, phi, offset)
    t3 = target_point(leader, phi, Point(0.0, -c))
    if math.hypot(*t0) < math.hypot(*t3):
        return Selection(zone, Choice.T0, t0)
    return Selection(zone, Choice.T3, t3)
