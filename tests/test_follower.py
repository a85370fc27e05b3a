"""A follower's per-tick brain on hand-made readings: when it stops, what it
steers to, what it tells the EKF, and its defaults."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from formation_swarm import scenario as scenario_mod
from formation_swarm.agents import fuzzy as fz
from formation_swarm.agents.avoidance import Choice
from formation_swarm.agents.follower import Follower, FollowerParams
from formation_swarm.agents.geometry import Point, errors, leader_point, target_from_reading, target_point
from formation_swarm.agents.lpsi import control as lpsi_control
from tests.test_avoidance import fly_the_change

READING = (2.0, 0.2, 0.3)  # rho_r, phi, beta: the reference 2 m ahead, a little right, turned left
OFFSET = Point(-1.5, -1.0)


def test_no_reading_yet_means_standing_still() -> None:
    d = Follower(FollowerParams(), OFFSET).step(None)
    assert (d.left_mps, d.right_mps) == (0.0, 0.0)
    assert math.isnan(d.vn)
    assert d.estimate is None
    assert d.measured is None


def test_it_stops_once_it_has_had_no_reading_for_lost_after_s() -> None:
    f = Follower(FollowerParams(lost_after_s=0.1, dt_s=0.05), OFFSET)
    assert f.step(READING).left_mps != 0.0
    kept = [f.step(None) for _ in range(3)]
    # 0.05 s and 0.10 s without a reading: still flying on the EKF; past 0.1 s: stopped.
    assert [d.left_mps != 0.0 for d in kept] == [True, True, False]
    assert (kept[2].left_mps, kept[2].right_mps) == (0.0, 0.0)
    assert f._last_cmd == (0.0, 0.0)  # the EKF's next prediction: the robot stood still
    assert f.step(READING).left_mps != 0.0  # a reading again: flying again


def test_the_measured_target_is_eq_1_2_on_the_reading() -> None:
    d = Follower(FollowerParams(), OFFSET).step(READING)
    assert d.measured == pytest.approx(target_from_reading(*READING, 0.1, OFFSET), abs=1e-12)


def test_without_the_ekf_it_acts_on_the_reading_itself() -> None:
    p = FollowerParams(use_ekf=False)
    f = Follower(p, OFFSET)
    d = f.step(READING)
    rho_r, phi, beta = READING
    goal = target_point(leader_point(rho_r, phi, beta, p.marker_offset_m), phi, OFFSET)
    err = errors(goal, None, phi)
    vn, wheels = fz.control(err.alpha_rad, err.rho_m, 0.0, p.dt_s, p.fuzzy, p.speed)
    assert d.estimate == pytest.approx(goal, abs=1e-12)
    assert (d.left_mps, d.right_mps, d.vn) == pytest.approx((wheels.left_mps, wheels.right_mps, vn), abs=1e-12)
    assert d.estimate_cov is None
    again = f.step(None)  # no new reading: the last one still counts
    assert again.left_mps != 0.0


def test_lpsi_without_the_ekf_assumes_a_still_reference() -> None:
    p = FollowerParams(use_ekf=False, law="lpsi")
    d = Follower(p, OFFSET).step(READING)
    rho_r, phi, beta = READING
    want = lpsi_control(leader_point(rho_r, phi, beta, p.marker_offset_m), phi, 0.0, 0.0, OFFSET, p.width_m, p.lpsi)
    assert (d.left_mps, d.right_mps) == pytest.approx(want, abs=1e-12)
    assert math.isnan(d.vn)


def test_lpsi_has_no_avoidance_manoeuvre() -> None:
    f = Follower(FollowerParams(law="lpsi"), OFFSET)
    f.step(READING)
    f.set_offset(Point(1.5, -1.0))
    d = f.step(READING)
    assert (d.steering_to, d.changing, f.changing) == (Choice.T0, False, False)


def test_a_new_slot_starts_a_change_and_the_same_slot_does_not() -> None:
    f = Follower(FollowerParams(), OFFSET)
    assert f.offset == OFFSET
    f.set_offset(Point(-1.5, -1.0))
    assert not f.changing
    for new in (Point(-2.0, -1.0), Point(1.0, -1.0), Point(-1.5, -3.0), Point(-1.5, 0.5)):
        g = Follower(FollowerParams(), OFFSET)
        g.set_offset(new)
        assert g.changing, new
        assert g.offset == new


def test_a_follower_starts_on_its_slot_not_on_an_avoidance_target() -> None:
    # The reference behind-left of the follower: the follower is in zone I of eq. 13.
    d = Follower(FollowerParams(), OFFSET).step((2.0, 0.0, -2.5))
    assert (d.steering_to, d.changing) == (Choice.T0, False)


def test_a_near_new_slot_ends_the_change_at_once() -> None:
    f = Follower(FollowerParams(), Point(0.0, -2.0))
    f.step((2.0, 0.0, 0.0))  # right behind the reference, on its slot
    f.set_offset(Point(0.0, -2.2))  # zone III, T0 nearer than T3
    d = f.step((2.0, 0.0, 0.0))
    assert (d.steering_to, d.changing) == (Choice.T0, False)


def test_drho_restarts_when_the_target_switches(tmp_path: Path) -> None:
    """Eq. 6 across a change of target (T1, T3, T0): drho is 0 on the tick the
    target switches, rho_t - rho_(t-1) otherwise."""
    decisions = []
    original = Follower.step

    def spy(self: Follower, reading: tuple | None) -> object:
        d = original(self, reading)
        decisions.append(d)
        return d

    Follower.step = spy  # type: ignore[method-assign]
    try:
        fly_the_change(tmp_path, seed=0, avoidance=True)
    finally:
        Follower.step = original  # type: ignore[method-assign]
    switches = 0
    for prev, d in zip(decisions, decisions[1:], strict=False):
        if math.isnan(prev.rho_m):
            continue
        if d.steering_to != prev.steering_to:
            switches += 1
            assert d.drho_m == 0.0
        else:
            assert d.drho_m == pytest.approx(d.rho_m - prev.rho_m, abs=1e-12)
    assert switches >= 2  # T0 -> an avoidance target -> ... -> T0


def test_defaults_are_the_scenario_files_defaults() -> None:
    """One source per fact: a scenario that sets nothing gets the follower defaults."""
    sc = scenario_mod.load(Path(__file__).parent.parent / "scenarios" / "fig7_turn_vn_dynamic.toml")
    p, default = sc.followers[2], FollowerParams()
    for name in ("width_m", "marker_offset_m", "dt_s", "clearance_m", "lost_after_s", "use_ekf", "law"):
        assert getattr(p, name) == getattr(default, name), name
    assert (default.clearance_m, default.lost_after_s) == (1.0, 1.0)


def test_parameters_are_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        FollowerParams().dt_s = 1.0  # type: ignore[misc]
