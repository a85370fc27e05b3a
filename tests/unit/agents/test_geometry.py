"""Eq. 1-6 and 11-13 on hand-computed cases, and against the world's camera."""

from __future__ import annotations

import math

import numpy as np
import pytest

from formation_swarm.agents import fuzzy as fz
from formation_swarm.agents import geometry as g
from formation_swarm.agents.avoidance import Choice, Zone, select_target, zone_of
from formation_swarm.agents.formation import Formation, Slot, line, wedge
from formation_swarm.agents.geometry import Point
from formation_swarm.world.camera import true_reading
from formation_swarm.world.kinematics import Pose, from_body_frame, to_body_frame


def test_leader_straight_ahead() -> None:
    # Marker 2 m ahead, leader aligned: centre is d further ahead.
    pr = g.leader_point(2.0, 0.0, 0.0, 0.1)
    assert pr == pytest.approx((0.0, 2.1))
    # Offset 1 m behind and 1 m left of the leader.
    pg = g.target_point(pr, 0.0, Point(-1.0, -1.0))
    assert pg == pytest.approx((-1.0, 1.1))
    e = g.errors(pg, None)
    assert e.alpha_rad == pytest.approx(math.atan2(-1.0, 1.1))
    assert e.rho_m == pytest.approx(math.hypot(1.0, 1.1))
    assert e.drho_m == 0.0
    assert g.errors(pg, 2.0).drho_m == pytest.approx(math.hypot(1.0, 1.1) - 2.0)


def test_leader_at_bearing_and_rotated() -> None:
    # Marker at 2 m, 30 deg to the right; leader turned 90 deg left (facing -x).
    beta, phi, d = math.radians(30), math.pi / 2, 0.2
    pr = g.leader_point(2.0, phi, beta, d)
    # Marker at (1, sqrt 3); centre is d along the leader's heading (-x).
    assert pr == pytest.approx((1.0 - 0.2, math.sqrt(3.0)))
    # P_vt = (0, -1): 1 m behind the leader, i.e. +x in the follower frame.
    assert g.target_point(pr, phi, Point(0.0, -1.0)) == pytest.approx((1.8, math.sqrt(3.0)))
    # A target on the follower's right has alpha > 0.
    assert g.errors(Point(1.0, 1.0), None).alpha_rad == pytest.approx(math.pi / 4)
    # A follower ahead of its target along the reference's heading has a
    # negative rho (eq. 5, signed): here the reference faces the follower's way.
    behind = g.errors(Point(0.3, -0.4), 0.2, phi_rad=0.0)
    assert behind.rho_m == pytest.approx(-0.5)
    assert behind.drho_m == pytest.approx(-0.7)
    # The same target with the reference facing the other way is still ahead.
    assert g.errors(Point(0.3, -0.4), None, phi_rad=math.pi).rho_m == pytest.approx(0.5)


def test_geometry_inverts_the_camera_for_random_poses() -> None:
    """Eq. 1-2 on a noise-free reading give the true target (world maths)."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        f = Pose(*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi))
        lead = Pose(*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi))
        off = Point(*rng.uniform(-2, 2, 2))
        d = float(rng.uniform(0, 0.3))
        rho, phi, beta = true_reading(f, lead, d)
        pg = g.target_from_reading(rho, phi, beta, d, off)
        want = to_body_frame(f, *from_body_frame(lead, off.x_m, off.y_m))
        assert pg == pytest.approx(want, abs=1e-9)
        pr = g.leader_point(rho, phi, beta, d)
        # Eq. 11-12: the follower seen from the leader.
        assert g.follower_in_leader_frame(pr, phi) == pytest.approx(to_body_frame(lead, f.x_m, f.y_m), abs=1e-9)


@pytest.mark.parametrize(
    ("follower_in_leader", "zone"),
    [((1.0, 1.0), Zone.I), ((-1.0, 1.0), Zone.II), ((1.0, -1.0), Zone.III), ((-1.0, -0.5), Zone.III)],
)
def test_zones_eq_11_12(follower_in_leader: tuple[float, float], zone: Zone) -> None:
    lead = Pose(0.0, 0.0, 0.3)
    fx, fy = from_body_frame(lead, *follower_in_leader)
    f = Pose(fx, fy, -0.8)
    pr_x, pr_y = to_body_frame(f, lead.x_m, lead.y_m)
    phi = lead.theta_rad - f.theta_rad
    assert zone_of(Point(pr_x, pr_y), phi) is zone


def _selection(follower_in_leader: tuple[float, float], offset: Point, clearance: float = 1.0) -> tuple:
    """Run eq. 13 from a follower placed in the leader frame; targets back in it."""
    lead = Pose(2.0, -1.0, 1.1)
    f = Pose(*from_body_frame(lead, *follower_in_leader), -0.4)
    pr = Point(*to_body_frame(f, lead.x_m, lead.y_m))
    sel = select_target(pr, lead.theta_rad - f.theta_rad, offset, clearance)
    return sel.zone, sel.choice, to_body_frame(lead, *from_body_frame(f, *sel.target))


def test_eq13_zone_i_goes_beside_right() -> None:
    zone, choice, t = _selection((0.5, 0.5), Point(0.0, -1.5))
    assert (zone, choice) == (Zone.I, Choice.T1)
    assert t == pytest.approx((1.0, 0.0))


def test_eq13_zone_ii_goes_beside_left() -> None:
    zone, choice, t = _selection((-0.5, 2.0), Point(0.0, -1.5))
    assert (zone, choice) == (Zone.II, Choice.T2)
    assert t == pytest.approx((-1.0, 0.0))


def test_eq13_zone_iii_far_target_goes_behind_first() -> None:
    # Behind-right, new slot behind-left far away: T3 (behind the leader) is nearer.
    zone, choice, t = _selection((1.5, -1.0), Point(-2.0, -3.0))
    assert (zone, choice) == (Zone.III, Choice.T3)
    assert t == pytest.approx((0.0, -1.0))


def test_eq13_zone_iii_near_target_goes_straight() -> None:
    zone, choice, t = _selection((0.2, -1.4), Point(0.0, -1.5))
    assert (zone, choice) == (Zone.III, Choice.T0)
    assert t == pytest.approx((0.0, -1.5))


def test_formations_triangle_and_line() -> None:
    tri = wedge(3, 1.5, 1.5)
    assert tri.leader == 1
    assert tri.slots[2] == Slot(1, Point(-1.5, -1.5))
    assert tri.slots[3] == Slot(2, Point(3.0, 0.0))
    assert tri.slot_positions()[3] == pytest.approx((1.5, -1.5))
    ln = line(3, 1.5)
    assert ln.slots[3] == Slot(2, Point(0.0, -1.5))
    big = wedge(7, 1.0, 1.0)
    assert big.slot_positions()[6] == pytest.approx((-3.0, -3.0))
    assert big.slot_positions()[7] == pytest.approx((3.0, -3.0))


@pytest.mark.parametrize(
    ("slots", "match"),
    [
        ({2: Slot(2, Point(0, -1))}, "references itself"),
        ({2: Slot(3, Point(0, -1)), 3: Slot(2, Point(0, -1))}, "cycle"),
        ({2: Slot(1, Point(math.nan, -1))}, "offset x"),
        ({0: Slot(1, Point(0, -1))}, "robot id"),
        ({}, "no follower"),
    ],
)
def test_bad_formations(slots: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Formation("f", slots)


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: g.leader_point(-1.0, 0.0, 0.0, 0.1), "rho_m"),
        (lambda: g.leader_point(1.0, math.nan, 0.0, 0.1), "phi_rad"),
        (lambda: g.leader_point(1.0, 0.0, math.inf, 0.1), "beta_rad"),
        (lambda: g.leader_point(1.0, 0.0, 0.0, -0.1), "marker_offset_m"),
        (lambda: g.errors(Point(math.nan, 1.0), None), "target.x_m"),
        (lambda: g.lookahead_bearing(Point(0.1, 0.3), 0.0, -1.0), "lookahead_m"),
        (lambda: g.lookahead_bearing(Point(0.1, 0.3), math.nan, 1.0), "phi_rad"),
        (lambda: select_target(Point(0.0, 1.0), 0.0, Point(0, -1), 0.0), "clearance_m"),
        (lambda: line(1, 1.0), "n must be"),
        (lambda: wedge(3, -1.0, 1.0), "lateral_m"),
    ],
)
def test_bad_input_names_the_parameter(call: object, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        call()  # type: ignore[operator]


def test_zone_and_choice_numbers_are_the_papers_and_the_wires() -> None:
    """Zones I-III (eq. 11-12); the choice is sent as Telemetry.steering_to (0-3)."""
    assert [int(z) for z in Zone] == [1, 2, 3]
    assert [int(c) for c in Choice] == [0, 1, 2, 3]


@pytest.mark.parametrize(
    ("follower_in_leader", "zone"),
    [((0.0, 1.0), Zone.II), ((1.0, 0.0), Zone.III), ((-1.0, 0.0), Zone.III), ((0.0, 0.0), Zone.III)],
)
def test_zone_boundaries_go_where_the_strict_inequalities_leave_them(follower_in_leader: tuple, zone: Zone) -> None:
    # The leader at the origin facing +y of the follower frame: P_xy = -P_r.
    px, py = follower_in_leader
    assert zone_of(Point(-px, -py), 0.0) is zone


def test_eq13_zone_iii_tie_goes_behind() -> None:
    # T0 and T3 equally far from the follower: "T0 nearer" is strict, so T3.
    sel = select_target(Point(0.0, 2.0), 0.0, Point(0.0, -1.0), clearance_m=1.0)
    assert (sel.zone, sel.choice) == (Zone.III, Choice.T3)
    sel = select_target(Point(0.0, 2.0), 0.0, Point(0.0, -1.1), clearance_m=1.0)
    assert sel.choice is Choice.T0


@pytest.mark.parametrize(("leader", "name"), [((math.nan, 1.0), "leader.x_m"), ((1.0, math.inf), "leader.y_m")])
def test_eq13_bad_leader_names_the_coordinate(leader: tuple, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        select_target(Point(*leader), 0.0, Point(0.0, -1.0), 1.0)


def test_formation_edge_cases() -> None:
    import dataclasses

    from formation_swarm.agents.formation import from_slot_positions

    assert line(2, 1.0).slots == {2: Slot(1, Point(0.0, -1.0))}
    assert wedge(2, 1.0, 1.0).slots == {2: Slot(1, Point(-1.0, -1.0))}
    assert line(3, 1.5).robots == [1, 2, 3]
    flipped = Formation("f", {1: Slot(2, Point(0.0, -1.0))})  # robot 1 may follow robot 2
    assert flipped.leader == 2
    assert from_slot_positions("p", {4: Point(0, 0), 9: Point(1, -1)}).slots == {9: Slot(4, Point(1.0, -1.0))}
    with pytest.raises(ValueError, match="at least 2"):
        from_slot_positions("p", {1: Point(0, 0)})
    with pytest.raises(ValueError, match="several leaders"):
        Formation("f", {2: Slot(1, Point(0, -1)), 4: Slot(3, Point(0, -1))})
    with pytest.raises(ValueError, match="robot id"):
        Formation("f", {True: Slot(2, Point(0, -1))})
    with pytest.raises(dataclasses.FrozenInstanceError):
        line(2, 1.0).name = "x"  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        Slot(1, Point(0, 0)).reference = 2  # type: ignore[misc]


def test_rho_sign_by_default_takes_the_reference_along_the_followers_heading() -> None:
    # Behind-left of the follower, slightly behind: "ahead of the target" along phi = 0.
    assert g.errors(Point(-1.0, -0.2), None).rho_m < 0.0
    assert g.errors(Point(-1.0, -0.2), None, phi_rad=1.0).rho_m > 0.0


def test_the_signed_rho_jumps_where_a_follower_is_level_with_its_target_to_its_side() -> None:
    # Eq. 5's sign (docs/paper.md): the target 0.5 m to the follower's right, 1 mm ahead of it, then 1 mm behind.
    p = fz.FuzzyParams()
    ahead = g.errors(Point(0.5, 0.001), None)
    behind = g.errors(Point(0.5, -0.001), ahead.rho_m)
    assert ahead.rho_m == pytest.approx(0.5, abs=1e-5)
    assert behind.rho_m == pytest.approx(-0.5, abs=1e-5)
    assert behind.drho_m / 0.05 == pytest.approx(-20.0, abs=1e-3)  # FIS-2's input, m/s
    vn_ahead, wheels_ahead = fz.control(ahead.alpha_rad, ahead.rho_m, 0.0, 0.05, p=p, mode=fz.SpeedMode())
    vn_behind, wheels_behind = fz.control(behind.alpha_rad, behind.rho_m, behind.drho_m, 0.05, p=p, mode=fz.SpeedMode())
    assert vn_ahead == pytest.approx(1.7)  # Middle
    assert (wheels_ahead.left_mps, wheels_ahead.right_mps) == pytest.approx((1.7, 1.2))  # turns right, to it
    assert vn_behind == pytest.approx(1.5)  # the -20 m/s forces Low
    assert (wheels_behind.left_mps, wheels_behind.right_mps) == pytest.approx((1.0, 1.0))  # Close: straight on
    # Without the kick of delta-rho V_N would stay Middle, wheels (1.2, 1.2): the sign alone ends the steering.
    assert fz.fis2(0.0, behind.rho_m, p) == pytest.approx(1.7)


def test_an_alpha_beyond_pi_is_wrapped_not_saturated() -> None:
    # atan2 keeps eq. 4's alpha in [-pi, pi]; an input beyond it is the same direction, wrapped.
    p = fz.FuzzyParams()
    beyond = fz.control(math.pi + 0.3, 1.5, 0.0, 0.05, p=p, mode=fz.SpeedMode(1.5))
    assert beyond == fz.control(-math.pi + 0.3, 1.5, 0.0, 0.05, p=p, mode=fz.SpeedMode(1.5))
    assert beyond[1].left_mps < beyond[1].right_mps  # the target is behind-left: turn left
    assert (
        fz.control(math.pi, 1.5, 0.0, 0.05, p=p, mode=fz.SpeedMode(1.5))[1].left_mps > 1.5
    )  # pi itself unchanged: Left


def test_the_lookahead_bearing_aims_past_the_target_along_the_references_heading() -> None:
    """0 m: eq. 4's alpha. 1 m with the reference heading as the follower
    (phi = 0): the point 1 m farther ahead, so a target 0.1 m to the right and
    0.35 m ahead turns it by atan(0.1 / 1.35), not atan(0.1 / 0.35); with the
    reference turned 90 degrees to the left (phi = pi/2, its heading the
    follower's -x), the point lies 1 m to the left of the target."""
    target = Point(0.1, 0.35)
    assert g.lookahead_bearing(target, 0.3, 0.0) == g.errors(target, None, 0.3).alpha_rad
    assert g.lookahead_bearing(target, 0.0, 1.0) == pytest.approx(math.atan2(0.1, 1.35))
    assert math.degrees(g.errors(target, None).alpha_rad) == pytest.approx(15.9, abs=0.05)
    assert math.degrees(g.lookahead_bearing(target, 0.0, 1.0)) == pytest.approx(4.24, abs=0.01)
    assert g.lookahead_bearing(target, math.pi / 2, 1.0) == pytest.approx(math.atan2(-0.9, 0.35))
