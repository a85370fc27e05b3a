"""The separation-bearing (l-psi) baseline controller."""

from __future__ import annotations

import math

import pytest

from formation_swarm.agents.follower import FollowerParams, law_class
from formation_swarm.agents.geometry import Point
from formation_swarm.agents.lpsi import LpsiParams, control
from formation_swarm.studies.sim import paper_turning_setup, run

P = LpsiParams()


@pytest.mark.parametrize("offset", [Point(-1.5, -1.5), Point(2.0, -0.5), Point(0.0, -3.0)])
def test_on_its_slot_behind_a_straight_leader_it_just_follows(offset: Point) -> None:
    # Same heading as the leader, centre on the target: dl/dt = dpsi/dt = 0 needs v = v_ref, w = 0.
    leader = Point(-offset.x_m, -offset.y_m)
    left, right = control(leader, 0.0, 1.5, 0.0, offset=offset, width_m=0.5, p=P)
    assert left == pytest.approx(1.5, abs=1e-9)
    assert right == pytest.approx(1.5, abs=1e-9)


def test_lagging_follower_speeds_up_and_a_left_offset_turns_it_left() -> None:
    offset = Point(0.0, -1.5)  # straight behind
    left, right = control(Point(0.0, 3.0), 0.0, 1.0, 0.0, offset=offset, width_m=0.5, p=P)  # 1.5 m too far back
    assert left == right > 1.0
    left, right = control(Point(-1.0, 1.5), 0.0, 1.0, 0.0, offset=offset, width_m=0.5, p=P)  # leader 1 m to our left
    assert right > left


def test_wheels_are_clipped_to_the_actuator_limit() -> None:
    left, right = control(
        Point(0.0, 50.0), 0.0, 1.5, 0.0, offset=Point(0.0, -1.5), width_m=0.5, p=LpsiParams(max_wheel_mps=2.5)
    )
    assert left == right == 2.5


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_closed_loop_on_the_paper_turning_path_with_camera_noise(seed: int) -> None:
    res = run(paper_turning_setup(seed=seed, follower=FollowerParams(law="lpsi")))
    # Measured: RMS 0.08-0.09 m, max 0.19-0.29 m (seeds 0-4).
    assert res.rms(2) < 0.2
    assert res.max(2) < 0.5


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"l_gain": 0.0}, "l_gain"),
        ({"psi_gain": -1.0}, "psi_gain"),
        ({"d_m": math.nan}, "d_m"),
        ({"max_wheel_mps": 0.0}, "max_wheel"),
    ],
)
def test_bad_parameters_name_themselves(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        LpsiParams(**kwargs)


def test_bad_law_and_bad_input() -> None:
    with pytest.raises(ValueError, match="law"):
        FollowerParams(law="")
    with pytest.raises(ValueError, match="no law named 'pid'"):  # nor an entry point of that name
        law_class("pid")
    with pytest.raises(ValueError, match="v_ref_mps"):
        control(Point(0.0, 2.0), 0.0, math.nan, 0.0, offset=Point(0.0, -1.5), width_m=0.5, p=P)


def test_turning_splits_the_wheels_by_half_the_width_each() -> None:
    """A pure turn of the controlled point: v = 0 and w from B, wheels v -+ w L / 2."""
    # The reference 0.5 m right of where it should be: the follower must turn right.
    p = LpsiParams(max_wheel_mps=100.0)
    left, right = control(Point(0.5, 2.0), 0.0, 0.0, 0.0, offset=Point(0.0, -2.0), width_m=0.5, p=p)
    assert left > right
    left2, right2 = control(Point(0.5, 2.0), 0.0, 0.0, 0.0, offset=Point(0.0, -2.0), width_m=1.0, p=p)
    assert left2 + right2 == pytest.approx(left + right, abs=1e-12)  # the same v ...
    assert left2 - right2 == pytest.approx(2 * (left - right), abs=1e-12)  # ... twice the track, twice the split


def test_defaults_and_frozen() -> None:
    import dataclasses

    assert (P.l_gain, P.psi_gain, P.d_m, P.max_wheel_mps) == (1.0, 1.0, 0.25, 2.5)  # as docs/results.md states
    with pytest.raises(dataclasses.FrozenInstanceError):
        P.d_m = 1.0  # type: ignore[misc]
