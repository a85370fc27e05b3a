"""Differential-drive kinematics (eq. 7-10) against closed forms and scipy."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from formation_swarm.world.kinematics import Pose, body_twist, from_body_frame, step, to_body_frame, wrap_angle


def test_straight_line() -> None:
    p = Pose(1.0, 2.0, math.radians(30))
    for _ in range(100):
        p = step(p, 1.2, 1.2, 0.5, 0.05)
    assert p.x_m == pytest.approx(1.0 + 6.0 * math.cos(math.radians(30)), abs=1e-12)
    assert p.y_m == pytest.approx(2.0 + 6.0 * math.sin(math.radians(30)), abs=1e-12)
    assert p.theta_rad == pytest.approx(math.radians(30), abs=1e-15)


def test_constant_wheels_follow_the_closed_form_arc() -> None:
    vl, vr, width, dt = 1.0, 1.5, 0.5, 0.05
    v, w = body_twist(vl, vr, width)  # 1.25 m/s, +1 rad/s (left turn)
    radius = v / w
    p0 = Pose(0.0, 0.0, 0.0)
    p = p0
    for k in range(1, 400):
        p = step(p, vl, vr, width, dt)
        t = k * dt
        # Centre of the circle is `radius` to the robot's left at the start.
        assert p.x_m == pytest.approx(radius * math.sin(w * t), abs=1e-9)
        assert p.y_m == pytest.approx(radius * (1.0 - math.cos(w * t)), abs=1e-9)
        assert p.theta_rad == pytest.approx(wrap_angle(w * t), abs=1e-9)


def test_faster_left_wheel_turns_right() -> None:
    p = step(Pose(0.0, 0.0, math.pi / 2), 1.0, 0.5, 0.5, 0.1)
    assert p.theta_rad < math.pi / 2
    assert p.x_m > 0.0


def test_matches_scipy_ode_for_varying_wheel_speeds() -> None:
    from scipy.integrate import solve_ivp

    width, dt, n = 0.4, 0.05, 200
    rng = np.random.default_rng(3)
    wheels = rng.uniform(0.0, 2.0, (n, 2))
    p = Pose(0.5, -0.5, 1.0)
    state = np.array(p)
    for k in range(n):
        vl, vr = wheels[k]

        def rhs(_t: float, s: np.ndarray, vl: float = vl, vr: float = vr) -> list[float]:
            v, w = (vl + vr) / 2, (vr - vl) / width  # eq. 8-9, CCW positive
            return [v * math.cos(s[2]), v * math.sin(s[2]), w]  # eq. 7

        state = solve_ivp(rhs, (0, dt), state, rtol=1e-12, atol=1e-12).y[:, -1]
        p = step(p, vl, vr, width, dt)
    assert p.x_m == pytest.approx(state[0], abs=1e-8)
    assert p.y_m == pytest.approx(state[1], abs=1e-8)
    assert p.theta_rad == pytest.approx(wrap_angle(state[2]), abs=1e-8)


@pytest.mark.parametrize("angle", [0.0, 3.0, math.pi, -math.pi, 7.0, -7.0, 100.0])
def test_wrap_angle(angle: float) -> None:
    w = wrap_angle(angle)
    assert -math.pi <= w < math.pi
    assert math.cos(w) == pytest.approx(math.cos(angle))
    assert math.sin(w) == pytest.approx(math.sin(angle), abs=1e-12)


def test_body_frame_round_trip_and_axes() -> None:
    robot = Pose(1.0, 1.0, math.pi / 2)  # facing +y
    assert to_body_frame(robot, 1.0, 3.0) == pytest.approx((0.0, 2.0))  # ahead
    assert to_body_frame(robot, 2.0, 1.0) == pytest.approx((1.0, 0.0))  # to its right
    assert from_body_frame(robot, *to_body_frame(robot, -3.0, 4.5)) == pytest.approx((-3.0, 4.5))


@pytest.mark.parametrize(
    ("args", "name"),
    [
        ((Pose(0, 0, 0), 1.0, 1.0, -0.5, 0.1), "width_m"),
        ((Pose(0, 0, 0), 1.0, 1.0, 0.5, 0.0), "dt_s"),
        ((Pose(math.nan, 0, 0), 1.0, 1.0, 0.5, 0.1), "pose.x_m"),
        ((Pose(0, 0, 0), math.inf, 1.0, 0.5, 0.1), "v_left_mps"),
        ((Pose(0, 0, 0), 1.0, math.nan, 0.5, 0.1), "v_right_mps"),
    ],
)
def test_bad_input_names_the_parameter(args: tuple, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        step(*args)


def _step_by_parts(pose: Pose, vl: float, vr: float, width: float, dt: float) -> Pose:
    """The oracle: the step as body_twist and wrap_angle compose it (the step writes them out)."""
    x, y, th = pose
    v, w = body_twist(vl, vr, width)
    dth = w * dt
    if abs(dth) < 1e-9:
        mid = th + 0.5 * dth
        return Pose(x + v * dt * math.cos(mid), y + v * dt * math.sin(mid), wrap_angle(th + dth))
    radius = v / w
    th1 = th + dth
    return Pose(
        x + radius * (math.sin(th1) - math.sin(th)), y - radius * (math.cos(th1) - math.cos(th)), wrap_angle(th1)
    )


def test_the_step_is_its_parts_to_the_bit() -> None:
    """Random poses and wheel speeds, straight (equal wheels, or nearly) and turning."""
    rng = np.random.default_rng(7)
    for _ in range(5000):
        pose = Pose(*rng.uniform(-100, 100, 2).tolist(), float(rng.uniform(-4, 4)))
        vl = float(rng.choice([rng.uniform(-2, 2), 0.5, 0.0]))
        vr = float(rng.choice([rng.uniform(-2, 2), vl, vl + 1e-12, -vl]))
        got = step(pose, vl, vr, 0.3, 0.05)
        assert type(got) is Pose
        assert struct.pack("<3d", *got) == struct.pack("<3d", *_step_by_parts(pose, vl, vr, 0.3, 0.05))
