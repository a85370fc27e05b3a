"""The world's per-tick work over all robots at once (numpy) gives what the
per-robot loops give: every marker seen, every draw, every contact, the
readings' numbers but for numpy's last bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.camera import CameraFrame, CameraParams, observe
from formation_swarm.world.contacts import Contacts
from formation_swarm.world.engine import WorldEngine
from formation_swarm.world.kinematics import Pose


def _random_poses(gen: np.random.Generator) -> dict[int, Pose]:
    n = int(gen.integers(2, 25))
    spread = float(gen.choice([1.0, 6.0, 15.0, 300.0]))
    ids = gen.choice(np.arange(1, 200), n, replace=False)
    return {int(r): Pose(*gen.uniform(-spread, spread, 2).tolist(), float(gen.uniform(-4.0, 4.0))) for r in ids}


def test_a_frame_reads_every_camera_as_observe_does() -> None:
    """Up to CameraFrame.SCALAR_MAX robots bit for bit; beyond, numpy's distance
    and bearing may differ from math's in the last bit, never a marker or a draw."""
    gen = np.random.default_rng(11)
    observations = readings = 0
    for trial in range(400):
        poses = _random_poses(gen)
        params = CameraParams(
            fov_rad=float(gen.choice([2 * math.pi, 2.0, 1.0])), range_m=float(gen.choice([3.0, 10.0]))
        )
        frame = CameraFrame(poses, params)
        for rid in poses:
            a, b = np.random.default_rng([trial, rid]), np.random.default_rng([trial, rid])
            want = observe(rid, poses, params, a)
            got = frame.observe(rid, b)
            if len(poses) <= CameraFrame.SCALAR_MAX:
                assert got == want
            else:
                assert [m.robot_id for m in got] == [m.robot_id for m in want]
                assert np.allclose(np.array(got).reshape(-1, 4), np.array(want).reshape(-1, 4), rtol=0, atol=1e-12)
            assert a.random() == b.random()  # the same number of draws
            observations += 1
            readings += len(want)
    assert observations > 4000
    assert readings > 10000


def _at_distance(rho: float, beta: float, params: CameraParams) -> Pose:
    """A robot (heading 0) whose marker is at (rho, beta) from an observer at the origin heading +y."""
    xb, yb = rho * math.sin(beta), rho * math.cos(beta)
    return Pose(xb + params.marker_offset_m, yb, 0.0)  # body x is world x for heading pi/2


@pytest.mark.parametrize("scalar_max", [0, 1000], ids=["numpy", "pair by pair"])
@pytest.mark.parametrize("fov_rad", [2 * math.pi, 1.2])
def test_markers_on_the_edge_of_range_and_view_are_decided_as_the_reference_does(
    fov_rad: float, scalar_max: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Pair by pair as observe() decides; with numpy as the every-pair oracle
    (tests/unit/world/test_camera_index.py) decides, in numpy's numbers."""
    monkeypatch.setattr(CameraFrame, "SCALAR_MAX", scalar_max)
    params = CameraParams(fov_rad=fov_rad, range_m=5.0)
    observer = Pose(0.0, 0.0, 0.5 * math.pi)
    poses = {1: observer}
    half = 0.5 * fov_rad if fov_rad < 2 * math.pi else 1.0
    rid = 2
    for rho in (math.nextafter(5.0, 0.0), 5.0, math.nextafter(5.0, 9.0), 5.0 + 1e-12, 5.0 - 1e-12):
        for beta in (0.3, half, math.nextafter(half, 0.0), math.nextafter(half, 9.0), -half):
            poses[rid] = _at_distance(rho, beta, params)
            rid += 1
    got = CameraFrame(poses, params).observe(1, np.random.default_rng(3))
    if scalar_max:
        want = [m.robot_id for m in observe(1, poses, params, np.random.default_rng(3))]
    else:
        from tests.unit.world.test_camera_index import _every_pair_sees

        want = [m[0] for m in _every_pair_sees(poses, params)[1]]
    assert [m.robot_id for m in got] == want
    assert len(want) > 0  # some seen
    assert len(want) < len(poses) - 1  # some not


def _contacts_by_pairs(poses: dict[int, Pose], diameter_m: float, obstacles: list) -> tuple[float, set]:
    """The pair loop the world ran before: the minimum distance and the contacts."""
    ids = sorted(poses)
    touching, least = set(), math.inf
    for i, a in enumerate(ids):
        pa = poses[a]
        for b in ids[i + 1 :]:
            pb = poses[b]
            d = math.hypot(pa.x_m - pb.x_m, pa.y_m - pb.y_m)
            least = min(least, d)
            if d < diameter_m:
                touching.add((a, b))
        for k, ob in enumerate(obstacles):
            if math.hypot(pa.x_m - ob.x_m, pa.y_m - ob.y_m) < ob.radius_m + 0.5 * diameter_m:
                touching.add((a, -1 - k))
    return least, touching


@pytest.mark.parametrize("robots", [3, 12])  # measured pair by pair (CameraFrame.SCALAR_MAX), and with numpy
def test_contacts_and_the_closest_distance_are_the_pair_loops(robots: int) -> None:
    sc = scenario_mod.load(
        scenario_files.resolve("fig11_obstacles"), {"run.robots": robots, "leader.formation": "line"}
    )
    gen = np.random.default_rng(5)
    touches = 0
    for _ in range(300):
        contacts = Contacts(sc.diameter_m, sc.obstacles, sc.dt_s)
        centre = sc.obstacles[0]
        poses = {
            rid: Pose(centre.x_m + float(gen.uniform(-3, 3)), centre.y_m + float(gen.uniform(-3, 3)), 0.0)
            for rid in sc.robots
        }
        contacts.measure(poses, 0)
        least, touching = _contacts_by_pairs(poses, sc.diameter_m, list(sc.obstacles))
        assert contacts.min_distance_m == least
        assert contacts.touching == touching
        touches += len(touching)
    assert touches > 25 * robots


def test_the_engine_observes_every_robot_as_one_observation_at_a_time() -> None:
    sc = scenario_mod.load(scenario_files.resolve("fig11_obstacles"), {"run.robots": 10, "leader.formation": "line"})
    one, many = WorldEngine(sc, 4), WorldEngine(sc, 4)
    seen = 0
    for _ in range(40):
        ids = sorted(one.robots)
        got = many.observations(ids)
        for rid in ids:
            assert one.observation(rid) == got[rid]
            seen += len(got[rid][1])
        for eng in (one, many):
            for rid in ids:
                eng.set_command(rid, 0.8, 0.9 if rid % 2 else 0.7, 0, eng.time_s)
            eng.step(eng.time_s)
    assert seen > 100
