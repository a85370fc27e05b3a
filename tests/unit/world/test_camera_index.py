"""The grid the cameras and the contacts look through (world.grid) leaves out
no pair: on random layouts of up to 300 robots the indexed camera sees what a
camera measuring every pair sees, and the contacts are the pair loop's."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from formation_swarm.world.camera import CameraFrame, CameraParams, observe
from formation_swarm.world.contacts import Contacts
from formation_swarm.world.grid import ALL_PAIRS_MAX, near_pairs
from formation_swarm.world.kinematics import Pose
from tests.unit.world.test_camera_frame import _contacts_by_pairs


def _every_pair_sees(poses: dict[int, Pose], params: CameraParams) -> dict[int, list[tuple[int, float, float, float]]]:
    """The oracle: every observer against every marker, with numpy, no index."""
    ids = sorted(poses)
    a = np.array([poses[r] for r in ids], dtype=float)
    x, y, th = a[:, 0], a[:, 1], a[:, 2]
    c, s = np.array([math.cos(t) for t in th]), np.array([math.sin(t) for t in th])
    d = params.marker_offset_m
    dx = (x - d * c)[None, :] - x[:, None]
    dy = (y - d * s)[None, :] - y[:, None]
    xb = dx * s[:, None] - dy * c[:, None]
    yb = dx * c[:, None] + dy * s[:, None]
    rho, beta = np.sqrt(xb * xb + yb * yb), np.arctan2(xb, yb)
    phi = (th[None, :] - th[:, None] + math.pi) % (2 * math.pi) - math.pi
    seen = (rho <= params.range_m) & (np.abs(beta) <= 0.5 * params.fov_rad)
    np.fill_diagonal(seen, False)
    # What a camera without noise reports: the angles wrapped once more, as the noise's sum is.
    phi, beta = (phi + math.pi) % (2 * math.pi) - math.pi, (beta + math.pi) % (2 * math.pi) - math.pi
    return {
        rid: [(ids[j], *map(float, (rho[i, j], phi[i, j], beta[i, j]))) for j in np.flatnonzero(seen[i]).tolist()]
        for i, rid in enumerate(ids)
    }


def _layout(gen: np.random.Generator, n: int) -> dict[int, Pose]:
    """n robots: spread evenly, in clusters, in a line or on the cells' edges, anywhere on the plane."""
    kind = int(gen.integers(4))
    centre = gen.uniform(-1e4, 1e4, 2)
    if kind == 0:
        xy = gen.uniform(-40, 40, (n, 2))
    elif kind == 1:
        xy = gen.choice(gen.uniform(-60, 60, (4, 2)), n) + gen.normal(0, 2, (n, 2))
    elif kind == 2:
        xy = np.column_stack((np.arange(n) * gen.uniform(0.3, 1.5), gen.normal(0, 0.2, n)))
    else:  # on multiples of the range: markers at the cells' edges
        xy = gen.integers(-5, 5, (n, 2)) * 10.0 + gen.choice([0.0, 1e-12, -1e-12, 0.1], (n, 2))
    ids = gen.choice(np.arange(1, 2000), n, replace=False)
    return {int(r): Pose(*(xy[k] + centre).tolist(), float(gen.uniform(-4, 4))) for k, r in enumerate(ids)}


def test_the_indexed_camera_sees_what_every_pair_sees() -> None:
    gen = np.random.default_rng(44)
    readings = 0
    for trial in range(30):
        n = int(gen.integers(60, 300))  # beyond ALL_PAIRS_MAX: through the grid
        poses = _layout(gen, n)
        params = CameraParams(fov_rad=float(gen.choice([2 * math.pi, 2.0])), range_m=float(gen.choice([3.0, 10.0])))
        frame = CameraFrame(poses, params)
        no_noise = CameraParams(
            fov_rad=params.fov_rad, range_m=params.range_m, sigma_rho_m=0, sigma_phi_rad=0, sigma_beta_rad=0
        )
        want = _every_pair_sees(poses, params)
        got = CameraFrame(poses, no_noise).observe_many([(rid, np.random.default_rng(0)) for rid in poses])
        assert got == want, trial
        # With noise, each robot's own stream: the pair-by-pair reference's markers,
        # draws and numbers (but numpy's last bit).
        for rid in list(poses)[:5]:
            a, b = np.random.default_rng([trial, rid]), np.random.default_rng([trial, rid])
            noisy, reference = frame.observe(rid, a), observe(rid, poses, params, b)
            assert [m.robot_id for m in noisy] == [m.robot_id for m in reference]
            assert np.allclose(np.reshape(noisy, (-1, 4)), np.reshape(reference, (-1, 4)), rtol=0, atol=1e-12)
            assert a.random() == b.random()
        readings += sum(map(len, want.values()))
    assert readings > 20_000


def test_the_grid_finds_every_pair_within_its_radius() -> None:
    gen = np.random.default_rng(7)
    for _ in range(40):
        a, b = gen.normal(0, 30, (300, 2)), gen.normal(5, 30, (200, 2))
        radius = float(gen.uniform(0.5, 20))
        i, j = near_pairs(a, b, radius)
        d = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])
        within = set(zip(*np.nonzero(d <= radius), strict=True))
        assert within <= set(zip(i.tolist(), j.tolist(), strict=True))
        assert len(set(zip(i.tolist(), j.tolist(), strict=True))) == len(i)  # each pair once
        assert len(i) < 300 * 200 // 2  # and far fewer than every pair
    assert ALL_PAIRS_MAX < 300 * 200


@pytest.mark.parametrize("spread_m", [3.0, 40.0, 5000.0])  # touching; a swarm; nobody within 10 m
def test_contacts_through_the_grid_are_the_pair_loops(spread_m: float) -> None:
    gen = np.random.default_rng(9)
    diameter = 0.3
    obstacles = [SimpleNamespace(x_m=0.0, y_m=0.0, radius_m=1.0)]
    contacts = Contacts(diameter, obstacles, 0.05)
    least, touched = math.inf, 0
    for tick in range(15):
        n = int(gen.integers(60, 250))
        poses = {rid: Pose(*gen.uniform(-spread_m, spread_m, 2).tolist(), 0.0) for rid in range(1, n + 1)}
        contacts.measure(poses, tick)
        tick_least, touching = _contacts_by_pairs(poses, diameter, obstacles)
        least = min(least, tick_least)
        assert contacts.min_distance_m == least
        assert contacts.touching == touching
        touched += len(touching)
    assert touched > (100 if spread_m < 10 else -1)
