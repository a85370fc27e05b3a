"""The camera model: geometry, field of view, range, seeded noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from formation_swarm.world.camera import CameraParams, observe, true_reading
from formation_swarm.world.kinematics import Pose, wrap_angle


def test_reading_of_a_robot_straight_ahead() -> None:
    rho, phi, beta = true_reading(Pose(0, 0, 0), Pose(3.0, 0.0, 0.5), 0.1)
    # Marker 0.1 m behind the target along its heading 0.5 rad.
    mx, my = 3.0 - 0.1 * math.cos(0.5), -0.1 * math.sin(0.5)
    assert rho == pytest.approx(math.hypot(mx, my))
    assert phi == pytest.approx(0.5)
    assert beta == pytest.approx(math.atan2(-my, mx))  # right of the heading is +beta


def test_field_of_view_and_range_hide_markers() -> None:
    params = CameraParams(fov_rad=math.radians(90), range_m=5.0, sigma_rho_m=0, sigma_phi_rad=0, sigma_beta_rad=0)
    poses = {
        1: Pose(0.0, 0.0, 0.0),
        2: Pose(3.0, 0.5, 0.0),  # ahead, in view
        3: Pose(-3.0, 0.0, 0.0),  # behind: outside the 90 deg cone
        4: Pose(8.0, 0.0, 0.0),  # ahead but beyond 5 m
        5: Pose(2.0, 2.5, 0.0),  # 51 deg left: outside +-45 deg
    }
    seen = observe(1, poses, params, np.random.default_rng(0))
    assert [m.robot_id for m in seen] == [2]
    assert seen[0].rho_m == pytest.approx(true_reading(poses[1], poses[2], params.marker_offset_m)[0])


def test_noise_statistics_and_seeding() -> None:
    params = CameraParams(sigma_rho_m=0.05, sigma_phi_rad=0.03, sigma_beta_rad=0.02)
    poses = {1: Pose(0, 0, 0), 2: Pose(2.0, 0.3, 0.2)}
    truth = true_reading(poses[1], poses[2], params.marker_offset_m)
    rng = np.random.default_rng(42)
    samples = np.array([observe(1, poses, params, rng)[0][1:] for _ in range(20000)])
    err = samples - np.array(truth)
    assert np.abs(err.mean(axis=0)).max() < 0.002
    assert err.std(axis=0) == pytest.approx([0.05, 0.03, 0.02], rel=0.03)
    a = observe(1, poses, params, np.random.default_rng(5))
    b = observe(1, poses, params, np.random.default_rng(5))
    c = observe(1, poses, params, np.random.default_rng(6))
    assert a == b
    assert a != c


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"fov_rad": 0.0}, "fov_rad"),
        ({"fov_rad": 7.0}, "fov_rad"),
        ({"range_m": -1.0}, "range_m"),
        ({"sigma_rho_m": math.nan}, "sigma_rho_m"),
        ({"marker_offset_m": -0.1}, "marker_offset_m"),
    ],
)
def test_bad_camera_parameters(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        CameraParams(**kwargs)


def test_noise_is_three_draws_per_marker_in_view_in_id_order_added_to_the_truth() -> None:
    """The documented stream (rho, phi, beta per marker in view, by robot id): same
    seed, same readings, so the same seed gives the same run."""
    params = CameraParams(range_m=3.0)
    poses = {1: Pose(0.0, 0.0, 0.3), 2: Pose(9.0, 0.0, 0.0), 3: Pose(0.05, 0.02, -0.2), 4: Pose(-1.0, 2.0, 3.0)}
    used = np.random.default_rng(11)
    seen = observe(1, poses, params, used)
    rng = np.random.default_rng(11)
    draws = rng.standard_normal(6).reshape(2, 3)  # robots 3 and 4 (2 out of range: no draw)
    want = []
    for rid, n in zip((3, 4), draws, strict=True):
        rho, phi, beta = true_reading(poses[1], poses[rid], params.marker_offset_m)
        want.append(
            (
                rid,
                max(0.0, rho + params.sigma_rho_m * n[0]),
                wrap_angle(phi + params.sigma_phi_rad * n[1]),
                wrap_angle(beta + params.sigma_beta_rad * n[2]),
            )
        )
    assert [v for m in seen for v in m] == pytest.approx([v for w in want for v in w], abs=1e-15)
    assert seen[0].rho_m >= 0.0  # robot 3 almost on top: the noise may not make rho negative
    assert used.random() == rng.random()  # six draws, no more


def test_a_marker_right_behind_is_seen_by_the_all_around_camera() -> None:
    params = CameraParams()
    poses = {1: Pose(0.0, 0.0, 0.0), 2: Pose(-3.0, 0.0, 0.0)}  # beta = -pi exactly
    assert [m.robot_id for m in observe(1, poses, params, np.random.default_rng(0))] == [2]


def test_a_hidden_marker_does_not_hide_the_next_ones() -> None:
    params = CameraParams(range_m=5.0)
    poses = {1: Pose(0.0, 0.0, 0.0), 2: Pose(50.0, 0.0, 0.0), 3: Pose(2.0, 0.0, 0.0)}
    assert [m.robot_id for m in observe(1, poses, params, np.random.default_rng(0))] == [3]


def test_defaults_are_the_scenario_files_and_frozen() -> None:
    import dataclasses

    from formation_swarm.spec import scenario as scenario_mod
    from tests.helpers import SCENARIOS

    assert scenario_mod.load(SCENARIOS / "fig7_turn_vn_dynamic.toml").camera == CameraParams()
    p = CameraParams()
    assert (p.fov_rad, p.range_m, p.sigma_rho_m, p.marker_offset_m) == (2 * math.pi, 10.0, 0.05, 0.1)
    assert (p.sigma_phi_rad, p.sigma_beta_rad) == (math.radians(3.0), math.radians(1.5))
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.range_m = 1.0  # type: ignore[misc]


def test_noise_never_makes_a_distance_negative() -> None:
    params = CameraParams(sigma_rho_m=1.0, marker_offset_m=0.0)
    poses = {1: Pose(0.0, 0.0, 0.0), 2: Pose(0.001, 0.0, 0.0)}
    rng = np.random.default_rng(3)
    rhos = [observe(1, poses, params, rng)[0].rho_m for _ in range(50)]
    assert min(rhos) == 0.0  # about half the draws are clamped
    assert sum(r == 0.0 for r in rhos) > 10
