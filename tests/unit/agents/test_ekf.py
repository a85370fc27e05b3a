"""The EKF of section 3: Jacobians, missed detections, noise reduction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from formation_swarm.agents.ekf import EkfParams, TargetEKF, _h_jacobian, _hx
from formation_swarm.agents.follower import FollowerParams
from formation_swarm.agents.geometry import MarkerReading, Point
from formation_swarm.studies.sim import paper_turning_setup, run
from tests.helpers.controllers import ByHand


def _z(rho_m: float, phi_rad: float, beta_rad: float) -> MarkerReading:
    return MarkerReading(rho_m=rho_m, phi_rad=phi_rad, beta_rad=beta_rad)


def _numeric_jacobian(f: object, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    cols = []
    for i in range(x.shape[0]):
        dx = np.zeros_like(x)
        dx[i, 0] = eps
        cols.append(((f(x + dx) - f(x - dx)) / (2 * eps))[:, 0])  # type: ignore[operator]
    return np.array(cols).T


def _filter_at(state: list[float]) -> TargetEKF:
    ekf = TargetEKF(EkfParams(), marker_offset_m=0.15, width_m=0.5)
    ekf.update(_z(2.0, 0.1, 0.2))
    ekf._kf.x = np.array(state, dtype=float).reshape(5, 1)
    return ekf


def test_measurement_jacobian_matches_finite_differences() -> None:
    x = np.array([[0.7], [2.1], [0.4], [1.2], [0.1]])
    num = _numeric_jacobian(lambda s: _hx(s, 0.15), x)
    assert _h_jacobian(x, 0.15) == pytest.approx(num, abs=1e-7)


def test_process_jacobian_matches_finite_differences() -> None:
    x0 = [0.7, 2.1, 0.4, 1.2, 0.3]

    def f(s: np.ndarray) -> np.ndarray:
        ekf = _filter_at(list(s[:, 0]))
        ekf.predict(1.1, 1.4, 0.05)
        return ekf._kf.x

    ekf = _filter_at(x0)
    ekf.predict(1.1, 1.4, 0.05)
    num = _numeric_jacobian(f, np.array(x0).reshape(5, 1))
    np.testing.assert_allclose(ekf._kf.F, num, atol=1e-7)


def test_ego_motion_of_a_still_reference() -> None:
    """A still reference 2 m ahead; the follower drives 1 m straight at it."""
    ekf = TargetEKF(EkfParams(), marker_offset_m=0.0, width_m=0.5)
    ekf.update(_z(2.0, 0.0, 0.0))
    for _ in range(20):
        ekf.predict(1.0, 1.0, 0.05)
    assert ekf.state[:3] == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    # Turning in place left by 90 deg puts the reference on the right.
    w = 0.5 * math.pi  # rad/s for 1 s
    for _ in range(20):
        ekf.predict(-w * 0.25, w * 0.25, 0.05)
    assert ekf.state[:3] == pytest.approx([1.0, 0.0, -math.pi / 2], abs=1e-9)


def test_missed_detection_only_predicts() -> None:
    ekf = TargetEKF(EkfParams(), marker_offset_m=0.1, width_m=0.5)
    ekf.update(_z(2.0, 0.0, 0.1))
    ekf.update(_z(2.0, 0.0, 0.1))
    ekf.predict(1.0, 1.0, 0.05)
    x_pred, p_pred = ekf.state, ekf.covariance
    ekf.update(None)
    assert np.array_equal(ekf.state, x_pred)
    assert np.array_equal(ekf.covariance, p_pred)
    ekf.predict(1.0, 1.0, 0.05)
    assert np.trace(ekf.covariance) > np.trace(p_pred)


def test_target_covariance_includes_heading_lever_arm() -> None:
    ekf = TargetEKF(EkfParams(), marker_offset_m=0.1, width_m=0.5)
    ekf.update(_z(2.0, 0.0, 0.0))
    _, near = ekf.target(Point(0.0, 0.0))
    _, far = ekf.target(Point(-3.0, 0.0))
    # A 3 m lateral offset adds 3 m * sigma_phi along the follower's y axis.
    assert far[1, 1] == pytest.approx(near[1, 1] + 9.0 * ekf.covariance[2, 2], rel=1e-9)


@pytest.mark.parametrize(
    ("name", "waypoints"),
    [("straight", ((0.0, 0.0), (0.0, 60.0))), ("turning", None)],
)
def test_ekf_error_well_below_raw_measurement(name: str, waypoints: object) -> None:
    """Measured here: ratio 0.47-0.49 on both paths over seeds 0-3."""
    ratios = []
    for seed in range(3):
        kw = {} if waypoints is None else {"waypoints": waypoints}
        r = run(paper_turning_setup(seed=seed, duration_s=40.0, **kw))
        raw = np.hypot(*(r.measured_targets[2] - r.true_targets[2]).T)
        est = np.hypot(*(r.estimated_targets[2] - r.true_targets[2]).T)
        ratios.append(np.sqrt(np.nanmean(est**2)) / np.sqrt(np.nanmean(raw**2)))
        assert np.sqrt(np.nanmean(raw**2)) > 0.1  # the camera noise is on
    assert max(ratios) < 0.55, ratios


@pytest.mark.parametrize(
    ("reading", "name"),
    [((math.nan, 0.0, 0.0), "rho_m"), ((1.0, math.inf, 0.0), "phi_rad"), ((1.0, 0.0, math.nan), "beta_rad")],
)
def test_bad_readings_name_the_field(reading: tuple, name: str) -> None:
    ekf = TargetEKF(EkfParams(), marker_offset_m=0.1, width_m=0.5)
    with pytest.raises(ValueError, match=name):
        ekf.update(_z(*reading))


def test_bad_parameters() -> None:
    with pytest.raises(ValueError, match="sigma_rho_m"):
        EkfParams(sigma_rho_m=0.0)
    with pytest.raises(ValueError, match="width_m"):
        TargetEKF(EkfParams(), 0.1, -1.0)


@pytest.mark.parametrize("rho_m", [1e200, 1e12, 1e6, 5e3])
def test_a_reading_far_outside_the_model_resets_the_filter_instead_of_raising(rho_m: float) -> None:
    """A wild reading (a spoofed or broken camera) must not crash the agent:
    the filter that diverges on it is counted and restarts from the next
    reading, exactly as a filter that never saw it would start."""
    f = ByHand(FollowerParams(), (-1.5, 0.0))
    for _ in range(20):
        f.step((2.0, 0.0, 0.1))
    d = f.step((rho_m, 0.0, 0.1))
    assert f.law.ekf.resets == 1
    assert (d.left_mps, d.right_mps, d.target, d.stop) == (0.0, 0.0, None, "lost")  # no estimate this tick: it stops
    assert d.values["ekf_resets"] == 1.0  # the count the agent's stats report
    fresh = ByHand(FollowerParams(), (-1.5, 0.0))
    for _ in range(40):
        d = f.step((2.0, 0.0, 0.1))
        fresh.step((2.0, 0.0, 0.1))
    assert f.law.ekf.initialized
    np.testing.assert_allclose(f.law.ekf.state, fresh.law.ekf.state, atol=1e-9)
    assert f.law.ekf.resets == 1


def test_a_plausible_far_reading_does_not_reset_the_filter() -> None:
    f = ByHand(FollowerParams(), (-1.5, 0.0))
    for _ in range(20):
        f.step((2.0, 0.0, 0.1))
    f.step((50.0, 0.0, 0.1))
    assert f.law.ekf.resets == 0


@pytest.mark.parametrize(
    ("state", "index", "shift"),
    [
        # The reference right behind the follower: bearing beta near +pi (eq. 1).
        ([0.05, -2.0, 0.3, 0.0, 0.0], 2, 0.08),
        # The reference facing the follower: relative orientation phi near +pi.
        ([0.5, 2.0, math.pi - 0.01, 0.0, 0.0], 1, 0.04),
    ],
    ids=["beta", "phi"],
)
def test_a_reading_across_plus_minus_pi_corrects_like_any_other(state: list[float], index: int, shift: float) -> None:
    """Angle residuals wrap (eq. 19-21): a reading a little past +pi, written as
    -pi + something by the camera, moves the estimate a little, exactly as the
    same reading written past +pi does."""
    predicted = _hx(np.array(state).reshape(5, 1), 0.1)[:, 0]  # (rho, beta, phi) the state predicts
    rho, beta, phi = predicted
    reading = [rho, phi, beta]  # the filter takes (rho, phi, beta)
    reading[index] += shift  # past +pi ...
    wrapped = list(reading)
    wrapped[index] -= 2 * math.pi  # ... as the camera reports it: just above -pi
    assert wrapped[index] < -math.pi + 0.1
    a, b = _filter_at(state), _filter_at(state)
    a.update(_z(*wrapped))
    b.update(_z(*reading))
    np.testing.assert_allclose(a.state, b.state, atol=1e-12)
    # A small correction: the position moves by centimetres, phi by less than the shift.
    moved = np.hypot(*(a.state[:2] - np.array(state[:2])))
    assert moved < 0.1, moved
    assert abs((a.state[2] - state[2] + math.pi) % (2 * math.pi) - math.pi) < shift


def test_parameters_are_frozen_and_checked() -> None:
    import dataclasses

    with pytest.raises(dataclasses.FrozenInstanceError):
        EkfParams().q_pos_m = 1.0  # type: ignore[misc]
    for name in ("q_pos_m", "q_phi_rad", "q_speed_mps", "q_turn_rps"):
        with pytest.raises(ValueError, match=name):
            EkfParams(**{name: -0.1})
    for name in ("initial_speed_sigma_mps", "initial_turn_sigma_rps", "sigma_phi_rad", "sigma_beta_rad"):
        with pytest.raises(ValueError, match=name):
            EkfParams(**{name: 0.0})


def test_first_reading_sets_the_state_and_a_first_order_covariance() -> None:
    """Eq. 1 inverted; its covariance from a numeric Jacobian of geometry.leader_point."""
    from formation_swarm.agents.geometry import leader_point

    p = EkfParams(initial_speed_sigma_mps=0.7, initial_turn_sigma_rps=0.3)
    ekf = TargetEKF(p, marker_offset_m=0.1, width_m=0.5)
    rho, phi, beta = 2.5, 0.4, 0.6
    ekf.update(_z(rho, phi, beta))
    assert ekf.state == pytest.approx([*leader_point(rho, phi, beta, 0.1), phi, 0.0, 0.0], abs=1e-12)
    eps = 1e-6
    cols = []
    for d_rho, d_beta in ((eps, 0.0), (0.0, eps)):
        hi = leader_point(rho + d_rho, phi, beta + d_beta, 0.1)
        lo = leader_point(rho - d_rho, phi, beta - d_beta, 0.1)
        cols.append([(hi[0] - lo[0]) / (2 * eps), (hi[1] - lo[1]) / (2 * eps)])
    j = np.array(cols).T
    want = j @ np.diag([p.sigma_rho_m**2, p.sigma_beta_rad**2]) @ j.T + np.eye(2) * (0.1 * p.sigma_phi_rad) ** 2
    cov = ekf.covariance
    np.testing.assert_allclose(cov[:2, :2], want, rtol=1e-6)
    assert np.diag(cov)[2:] == pytest.approx([p.sigma_phi_rad**2, 0.7**2, 0.3**2], rel=1e-12)
    assert np.count_nonzero(cov[2:, :]) == 3  # no correlation at the start


def test_process_noise_grows_with_the_step() -> None:
    p = EkfParams(q_pos_m=0.1, q_phi_rad=0.2, q_speed_mps=0.3, q_turn_rps=0.4)
    ekf = TargetEKF(p, marker_offset_m=0.1, width_m=0.5)
    ekf.update(_z(2.0, 0.0, 0.0))
    for dt in (0.05, 0.1, 0.05):
        ekf.predict(0.0, 0.0, dt)
        assert np.diag(ekf._kf.Q) == pytest.approx(np.array([0.01, 0.01, 0.04, 0.09, 0.16]) * dt, rel=1e-12)


def test_target_covariance_is_first_order_in_the_whole_state() -> None:
    ekf = _filter_at([0.7, 2.1, 0.4, 1.2, 0.1])
    ekf._kf.P = np.array([[0.3, 0.1, 0.05, 0.02, 0.01]] * 5) * 0 + np.diag([0.04, 0.09, 0.01, 0.25, 0.16])
    ekf._kf.P[0, 4] = ekf._kf.P[4, 0] = 0.02
    ekf._kf.P[1, 3] = ekf._kf.P[3, 1] = -0.03
    off = Point(-1.5, -1.0)
    eps = 1e-6
    base = ekf._kf.x.copy()
    cols = []
    for i in range(5):
        pts = []
        for s in (1, -1):
            ekf._kf.x = base.copy()
            ekf._kf.x[i, 0] += s * eps
            pts.append(np.array(ekf.target(off)[0]))
        cols.append((pts[0] - pts[1]) / (2 * eps))
    ekf._kf.x = base
    j = np.array(cols).T
    point, cov = ekf.target(off)
    np.testing.assert_allclose(cov, j @ ekf._kf.P @ j.T, rtol=1e-6, atol=1e-12)
    x, y, phi = base[:3, 0]
    assert point == pytest.approx(
        (x + off.x_m * math.cos(phi) - off.y_m * math.sin(phi), y + off.x_m * math.sin(phi) + off.y_m * math.cos(phi)),
        abs=1e-12,
    )


def test_the_filters_update_gives_filterpys_numbers_bit_for_bit() -> None:
    """Its update is filterpy's with a faster call of the same inverse: along a
    random walk of readings and steps, every array it keeps equals filterpy's."""
    from filterpy.kalman import ExtendedKalmanFilter

    rng = np.random.default_rng(7)
    ours, theirs = (TargetEKF(EkfParams(), marker_offset_m=0.15, width_m=0.5) for _ in range(2))
    for ekf in (ours, theirs):
        ekf.update(_z(2.0, 0.1, 0.2))
    theirs._kf.update = lambda *a, **kw: ExtendedKalmanFilter.update(theirs._kf, *a, **kw)  # filterpy's own
    for _ in range(200):
        left, right = rng.uniform(0.0, 0.6, 2).tolist()
        reading = None if rng.random() < 0.1 else _z(*rng.normal((2.0, 0.0, 0.0), (0.3, 0.3, 0.3)).tolist())
        for ekf in (ours, theirs):
            ekf.predict(left, right, 0.05)
            ekf.update(reading)
        for name in ("x", "P", "S", "SI", "K", "y", "z", "x_post", "P_post"):
            a, b = getattr(ours._kf, name), getattr(theirs._kf, name)
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name  # a missed reading's z: None
    assert ours.resets == theirs.resets == 0


@pytest.mark.parametrize(
    ("s", "error"),
    [
        (np.diag([1.0, 0.0, 1.0]), np.linalg.LinAlgError),  # singular
        (np.diag([1.0, math.nan, 1.0]), ValueError),  # not finite: scipy's own check
    ],
)
def test_an_innovation_covariance_scipy_refuses_is_refused_the_same_way(s: np.ndarray, error: type) -> None:
    from formation_swarm.agents.ekf import _inverse

    with pytest.raises(error):
        _inverse(s)
    s = np.array([[0.3, 0.01, 0.002], [0.01, 0.2, 0.003], [0.002, 0.003, 0.1]])
    assert np.array_equal(_inverse(s), __import__("scipy.linalg").linalg.inv(s))
