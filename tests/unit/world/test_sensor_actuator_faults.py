"""Sensor and actuator faults and wheel noise, executed by the world engine
(world/hardware_faults.py): driven tick by tick, no processes (the runs with
processes are in test_sensor_actuator_runs.py)."""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest

from formation_swarm.common.faults import Fault
from formation_swarm.spec import scenario as sm
from formation_swarm.world.camera import CameraParams, MarkerReading, true_reading
from formation_swarm.world.engine import WorldEngine
from formation_swarm.world.hardware_faults import CameraFaults, Wheels
from formation_swarm.world.kinematics import Pose, _step_unchecked, wrap_angle

FIG11 = "fig11_obstacles"  # three robots in a triangle: 1 leads 2, 2 leads 3; camera all around, 10 m


def _engine(faults: Sequence[str] = (), seed: int = 1, **overrides: object) -> WorldEngine:
    return WorldEngine(sm.load(FIG11, dict(overrides), faults), seed)


def _wheels(faults: Sequence[Fault], **fields: Any) -> Wheels:
    """Robot 2's wheels at 0.05 s a tick, seed 0, no noise, 3 m/s at most; ``fields`` override these."""
    defaults: dict[str, Any] = {"seed": 0, "robot_id": 2, "dt_s": 0.05, "noise_sigma_mps": 0.0, "max_wheel_mps": 3.0}
    return Wheels(faults, **(defaults | fields))


def _readings(eng: WorldEngine, rid: int) -> list[tuple[int, float, float, float]]:
    return eng.observation(rid)[1]


def _drive(eng: WorldEngine, commands: dict[int, tuple[float, float]], ticks: int = 1) -> None:
    for _ in range(ticks):
        for rid, (left, right) in commands.items():
            eng.set_command(rid, left, right, 0, eng.time_s)
        eng.step(eng.time_s)


# -- sensor faults -------------------------------------------------------------------


def test_a_blackout_hides_every_marker_for_exactly_its_ticks() -> None:
    eng = _engine(["blackout 3@1s for=2s"])
    seen = []
    for _ in range(100):
        seen.append((len(_readings(eng, 3)), len(_readings(eng, 2))))
        eng.step(eng.time_s)  # nobody commanded: the robots stand, both markers in view
    blind = [k for k, (n3, _) in enumerate(seen) if n3 == 0]
    assert blind == list(range(20, 60))  # 2 s / 0.05 s = 40 ticks, from tick round(1 / 0.05)
    assert all(n3 == 2 for k, (n3, _) in enumerate(seen) if k not in blind)  # and then readings again
    assert all(n2 == 2 for _, n2 in seen)  # robot 2's camera is not touched
    assert eng.summary()["sensor_faults"] == {"blackout 3@1s for=2s": {"3": {"ticks": 40, "blacked_out": 80}}}


def test_a_blackout_does_not_shift_the_camera_noise() -> None:
    """The camera draws its noise during the blackout too: afterwards robot 3
    reads exactly what it reads in the same run without the fault."""
    a, b = _engine(["blackout 3@1s for=2s"]), _engine()
    for k in range(80):
        ra, rb = _readings(a, 3), _readings(b, 3)
        assert ra == ([] if 20 <= k < 60 else rb)
        a.step(a.time_s)
        b.step(b.time_s)


def test_a_bias_shifts_the_mean_reading_by_the_bias() -> None:
    eng = _engine(["bias 2@0s rho_m=0.2 phi_deg=1 beta_deg=-2"])
    clean = _engine()
    sc = eng.scenario
    poses = {rid: r.pose for rid, r in eng.robots.items()}
    truth = true_reading(poses[2], poses[1], sc.camera.marker_offset_m)
    n = 2000
    errors = []
    for _ in range(n):
        got = {m[0]: m for m in _readings(eng, 2)}
        ref = {m[0]: m for m in _readings(clean, 2)}
        # Same seed, same camera noise: the biased reading is the clean one plus the bias, exactly.
        assert got[1][1] == pytest.approx(ref[1][1] + 0.2, abs=1e-12)
        assert got[1][2] == pytest.approx(wrap_angle(ref[1][2] + math.radians(1)), abs=1e-12)
        assert got[1][3] == pytest.approx(wrap_angle(ref[1][3] - math.radians(2)), abs=1e-12)
        errors.append((got[1][1] - truth[0], wrap_angle(got[1][2] - truth[1]), wrap_angle(got[1][3] - truth[2])))
        eng.step(eng.time_s)
        clean.step(clean.time_s)
    mean = np.mean(errors, axis=0)
    sigmas = (sc.camera.sigma_rho_m, sc.camera.sigma_phi_rad, sc.camera.sigma_beta_rad)
    for got_mean, bias, sigma in zip(mean, (0.2, math.radians(1), math.radians(-2)), sigmas, strict=True):
        assert abs(got_mean - bias) < 4 * sigma / math.sqrt(n)
    assert eng.summary()["sensor_faults"]["bias 2@0s beta_deg=-2 phi_deg=1 rho_m=0.2"]["2"] == {
        "ticks": n,
        "biased": 2 * n,
    }


def test_a_bias_wraps_the_angles_and_keeps_rho_non_negative() -> None:
    eng = _engine(["bias 3@0s rho_m=-50 phi_deg=270 beta_deg=-270"])
    for _ in range(50):
        for _rid, rho, phi, beta in _readings(eng, 3):
            assert rho == 0.0
            assert -math.pi <= phi < math.pi
            assert -math.pi <= beta < math.pi
        eng.step(eng.time_s)


def test_outliers_replace_a_fraction_p_of_the_readings_within_range_and_view() -> None:
    p, ticks = 0.2, 2500
    eng = _engine([f"outliers 2@0s p={p}"])
    clean = _engine()
    changed = 0
    for _ in range(ticks):
        got, ref = _readings(eng, 2), _readings(clean, 2)
        assert [m[0] for m in got] == [m[0] for m in ref]  # the same markers, some read wrong
        for g, r in zip(got, ref, strict=True):
            if g != r:
                changed += 1
                assert 0.0 <= g[1] <= eng.scenario.camera.range_m
                assert -math.pi <= g[2] <= math.pi
                assert -math.pi <= g[3] <= math.pi
        eng.step(eng.time_s)
        clean.step(clean.time_s)
    n = 2 * ticks  # robot 2 sees robots 1 and 3 on every tick
    assert abs(changed / n - p) < 3 * math.sqrt(p * (1 - p) / n)
    assert eng.summary()["sensor_faults"][f"outliers 2@0s p={p:g}"]["2"] == {"ticks": ticks, "replaced": changed}


def test_outliers_are_drawn_within_a_narrow_field_of_view_and_a_reduced_range() -> None:
    # 215 deg: the narrowest view in which fig11's robot 3 still sees robot 2, abeam, with the loader's margin.
    eng = _engine(["outliers 2@0s p=1", "range 2@0s m=4"], **{"camera.fov_deg": 215.0})
    sc = eng.scenario
    eng.robots[1].pose = Pose(-1.5, 1.0, math.pi / 2)  # 2.4 m ahead of robot 2
    eng.robots[3].pose = Pose(-1.5, -4.0, math.pi / 2)  # 2.5 m behind robot 2
    for _ in range(200):
        (seen,) = _readings(eng, 2)  # robot 3 is right behind: out of a 215 deg view
        assert seen[0] == 1
        assert 0.0 <= seen[1] <= 4.0
        assert abs(seen[3]) <= 0.5 * sc.camera.fov_rad
        eng.step(eng.time_s)


def test_a_reduced_range_drops_every_reading_beyond_it() -> None:
    eng, clean = _engine(["range 2@0s m=4"]), _engine()
    rng = np.random.default_rng(5)
    offset = eng.scenario.camera.marker_offset_m
    kept = cut = 0
    for _ in range(300):
        placed = {rid: Pose(*rng.uniform(-4.0, 4.0, 2).tolist(), 0.0) for rid in (1, 3)}  # 0-7 m from robot 2
        for e in (eng, clean):
            for rid, pose in placed.items():
                e.robots[rid].pose = pose
        poses = {rid: r.pose for rid, r in eng.robots.items()}
        got, ref = _readings(eng, 2), _readings(clean, 2)
        far = {m[0] for m in ref if true_reading(poses[2], poses[m[0]], offset)[0] > 4.0}
        assert got == [m for m in ref if m[0] not in far]  # exactly the markers within 4 m, untouched
        kept += len(got)
        cut += len(far)
        eng.step(eng.time_s)
        clean.step(clean.time_s)
    assert kept > 100
    assert cut > 100
    assert eng.summary()["sensor_faults"]["range 2@0s m=4"]["2"] == {"ticks": 300, "cut": cut}


def test_a_fault_shifts_no_other_random_stream() -> None:
    """Outliers on robot 3 leave robot 2's camera noise as it was; and robot 2's
    outliers draw the same with or without another fault scheduled before them."""
    base, extra = _engine(["outliers 2@0s p=0.3"]), _engine(["outliers 3@0s p=0.5", "outliers 2@0s p=0.3"])
    for _ in range(200):
        assert _readings(base, 2) == _readings(extra, 2)
        base.step(base.time_s)
        extra.step(extra.time_s)


def test_camera_faults_cannot_name_the_leader() -> None:
    with pytest.raises(sm.ScenarioError, match="robot 1 is the leader; it has no camera"):
        sm.load(FIG11, faults=["blackout 1@5s for=2s"])
    eng = _engine(["blackout *@0s"])  # '*': every follower
    assert set(eng.summary()["sensor_faults"]["blackout *@0s"]) == {"2", "3"}


# -- actuator faults -----------------------------------------------------------------


def _one_tick(faults: Sequence[str], command: tuple[float, float], rid: int = 2) -> tuple[Pose, Pose]:
    """Robot ``rid``'s pose before and after one tick of ``command``."""
    eng = _engine(faults)
    before = eng.robots[rid].pose
    _drive(eng, {rid: command})
    return before, eng.robots[rid].pose


def _kinematics(pose: Pose, left: float, right: float) -> Pose:
    sc = sm.load(FIG11)
    return _step_unchecked(*pose, left, right, width=sc.width_m, dt=sc.dt_s)


def test_a_stuck_wheel_turns_the_robot_on_the_other_wheel_alone() -> None:
    before, after = _one_tick(["stuck 2@0s wheel=left"], (1.0, 1.0))
    assert after == _kinematics(before, 0.0, 1.0)
    before, after = _one_tick(["stuck 2@0s wheel=both", "wheel_noise 2@0s sigma_mps=0.5"], (1.0, 1.0))
    assert after == before  # stuck wheels do not turn, noise or not


def test_a_stuck_wheel_turns_again_when_the_fault_ends() -> None:
    eng = _engine(["stuck 2@0s for=0.5s wheel=left"])
    _drive(eng, {2: (1.0, 1.0)}, ticks=10)
    before = eng.robots[2].pose
    _drive(eng, {2: (1.0, 1.0)})
    assert eng.robots[2].pose == _kinematics(before, 1.0, 1.0)
    assert eng.summary()["actuator_faults"]["stuck 2@0s for=0.5s wheel=left"] == {
        "2": {"ticks": 10, "moving_ticks": 10}
    }


def test_slip_loses_its_fraction_of_the_distance() -> None:
    slip, clean = _engine(["slip 3@0s fraction=0.4"]), _engine()
    start = slip.robots[3].pose
    for e in (slip, clean):
        _drive(e, {3: (1.0, 1.0)}, ticks=40)

    def travelled(e: WorldEngine) -> float:
        return math.hypot(e.robots[3].pose.x_m - start.x_m, e.robots[3].pose.y_m - start.y_m)

    assert travelled(clean) == pytest.approx(2.0, rel=1e-12)
    assert travelled(slip) == pytest.approx(0.6 * travelled(clean), rel=1e-12)
    before, after = _one_tick(["slip 2@0s fraction=0.4 wheel=right"], (1.0, 1.0))
    assert after == _kinematics(before, 1.0, 0.6)


def test_a_wheel_bias_scales_each_wheel() -> None:
    before, after = _one_tick(["wheel_bias 2@0s left=0.03 right=-0.03"], (1.0, 2.0))
    assert after == _kinematics(before, 1.03, 1.94)
    before, after = _one_tick(["wheel_bias 2@0s left=0.5"], (2.9, 2.9))
    assert after == _kinematics(before, 3.0, 2.9)  # the motors' limit holds after the bias


@pytest.mark.parametrize("source", ["fault", "scenario"])
def test_wheel_noise_has_the_standard_deviation_asked_for(source: str) -> None:
    sigma, n = 0.1, 10_000
    faults = [Fault.parse(f"wheel_noise 2@0s sigma_mps={sigma}")] if source == "fault" else []
    wheels = _wheels(faults, seed=4, noise_sigma_mps=0.0 if faults else sigma)
    speeds = np.array([wheels.turn(k, 1.0, 1.5) for k in range(n)])
    for wheel, commanded in ((0, 1.0), (1, 1.5)):
        assert abs(speeds[:, wheel].mean() - commanded) < 4 * sigma / math.sqrt(n)
        assert speeds[:, wheel].std(ddof=1) == pytest.approx(sigma, rel=0.05)
    assert abs(np.corrcoef(speeds[:, 0], speeds[:, 1])[0, 1]) < 4 / math.sqrt(n)  # independent wheels


def test_wheel_noise_moves_a_moving_robot_and_not_a_resting_one() -> None:
    noisy, clean = _engine(**{"robot.wheel_noise_mps": 0.1}), _engine()
    for e in (noisy, clean):
        _drive(e, {2: (1.0, 1.0), 3: (0.0, 0.0)}, ticks=20)
    assert noisy.robots[2].pose != clean.robots[2].pose
    d = math.hypot(
        noisy.robots[2].pose.x_m - clean.robots[2].pose.x_m, noisy.robots[2].pose.y_m - clean.robots[2].pose.y_m
    )
    assert d < 0.2  # 20 ticks of 5 mm per tick per wheel at most a few cm
    assert noisy.robots[3].pose == clean.robots[3].pose  # commanded to rest: no jitter
    assert noisy.robots[1].pose == clean.robots[1].pose  # never commanded (stale): at rest
    noisy.kill(2)
    parked = noisy.robots[2].pose
    _drive(noisy, {}, ticks=20)
    assert noisy.robots[2].pose == parked  # a dead robot stays where it died


def test_noise_is_clamped_to_the_motors_limit() -> None:
    wheels = _wheels([], noise_sigma_mps=0.5)
    speeds = np.array([wheels.turn(k, 2.9, -2.9) for k in range(2000)])
    assert speeds[:, 0].max() == 3.0
    assert speeds[:, 1].min() == -3.0
    assert np.all(np.abs(speeds) <= 3.0)


# -- determinism -----------------------------------------------------------------------


def _digest(sc_faults: Sequence[str], seed: int, **overrides: object) -> str:
    """A fixed drive of fig11: every robot observed and commanded on every tick."""
    eng = _engine(sc_faults, seed, **overrides)
    for k in range(200):
        for rid in eng.scenario.robots:
            eng.observation(rid)
            eng.set_command(rid, 1.0 + 0.1 * rid + (0.3 if k % 50 < 10 else 0.0), 1.2, 0, eng.time_s)
        eng.step(eng.time_s)
    return eng.digest()


FAULTY = [
    "wheel_noise *@0s sigma_mps=0.1",
    "outliers 3@0s p=0.05",
    "slip 3@2s for=2s fraction=0.4 wheel=right",
    "wheel_bias 2@0s left=0.03 right=-0.03",
    "stuck 2@5s for=1s wheel=left",
]


def test_a_run_without_faults_has_the_digest_it_had_before_faults_existed() -> None:
    # Computed with the engine of the commit before sensor and actuator faults.
    assert _digest([], 1) == "2fb542540eeeec8b55b447d47c6dfaf7ecc1c069638ba8662b19adfef365255c"
    assert _digest([], 1, **{"robot.wheel_noise_mps": 0.0}) == _digest([], 1)


def test_same_seed_same_faults_same_digest() -> None:
    assert _digest(FAULTY, 1) == _digest(FAULTY, 1)
    assert _digest(FAULTY, 1) != _digest(FAULTY, 2)
    assert _digest(FAULTY, 1) != _digest([], 1)
    noisy = {"robot.wheel_noise_mps": 0.05}
    assert _digest([], 3, **noisy) == _digest([], 3, **noisy) != _digest([], 3)


# -- exact effects on hand-set readings and commands -------------------------------------


def _key_rng(seed: int, rid: int, tag: int, fault: Fault, occurrence: int) -> np.random.Generator:
    """A fault's generator as documented: [seed, robot, tag, blake2b-32 of its text, occurrence + 1]."""
    text = int.from_bytes(hashlib.blake2b(str(fault).encode(), digest_size=4).digest(), "little")
    return np.random.default_rng([seed, rid, tag, text, occurrence + 1])


def test_outliers_are_exactly_the_documented_draws_scaled_to_range_and_view() -> None:
    faults = [Fault.parse("outliers 2@0s p=1"), Fault.parse("range 2@0s m=4"), Fault.parse("outliers 2@0s p=1")]
    camera = CameraParams(fov_rad=math.pi / 2, range_m=10.0)
    cam = CameraFaults(faults, seed=7, robot_id=2, dt_s=0.05, camera=camera)
    assert [(e.fault.kind, e.rng is None) for e in cam.effects] == [
        ("range", True),
        ("outliers", False),
        ("outliers", False),
    ]
    poses = {1: Pose(1.0, 0.0, 0.0), 2: Pose(0.0, 0.0, 0.0), 3: Pose(0.0, 2.0, 0.0)}
    readings = [MarkerReading(1, 1.0, 0.1, 0.2), MarkerReading(3, 2.0, 0.3, 0.4)]
    out = cam.apply(0, poses, readings)
    # Two identical faults: occurrences 0 and 1, each replacing both readings in turn.
    first = _key_rng(7, 2, 0x53454E53, faults[0], 0).random((2, 4)).tolist()
    second = _key_rng(7, 2, 0x53454E53, faults[0], 1).random((2, 4)).tolist()
    half_fov = math.pi / 4
    assert out == [
        MarkerReading(rid, rho * 4.0, math.pi * (2.0 * phi - 1.0), half_fov * (2.0 * beta - 1.0))
        for rid, (_u, rho, phi, beta) in zip((1, 3), second, strict=True)
    ]
    assert first != second
    assert [(e.ticks, e.effect) for e in cam.effects] == [(1, 0), (1, 2), (1, 2)]


def test_a_robot_turning_on_one_wheel_backwards_is_moving() -> None:
    wheels = _wheels([Fault.parse("wheel_bias 2@0s right=0.5")])
    assert wheels.turn(0, 0.0, -1.0) == (0.0, -1.5)
    assert wheels.turn(1, 0.0, 0.0) == (0.0, 0.0)
    assert [(e.ticks, e.effect) for e in wheels.effects] == [(2, 1)]


def test_wheel_noise_adds_the_documented_draws() -> None:
    f = Fault.parse("wheel_noise 2@0s sigma_mps=0.1")
    wheels = _wheels([f, Fault.parse("stuck 3@0s")], seed=3)
    rng = _key_rng(3, 2, 0x41435455, f, 0)
    for k in range(5):
        n_l, n_r = rng.standard_normal(2).tolist()
        assert wheels.turn(k, 1.0, -1.0) == (1.0 + 0.1 * n_l, -1.0 + 0.1 * n_r)
