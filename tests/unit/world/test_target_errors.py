"""world.metrics.TargetErrors: the target errors and the EKF's NEES, by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from formation_swarm.world.metrics import NEES_TICK_BOUND_99, TargetErrors, nees_body

NAN = math.nan


def test_nees_is_the_error_weighted_by_the_inverse_covariance_in_the_followers_frame() -> None:
    # Heading north (pi/2): the follower's x right is world +x, its y ahead world +y.
    cov = np.array([[0.04, 0.0, 0.01]])  # sigma 0.2 m right, 0.1 m ahead
    assert nees_body(np.array([math.pi / 2]), np.array([[0.2, 0.1]]), cov)[0] == pytest.approx(2.0)
    # Heading east (0): x right is world -y, y ahead world +x; the same error turned with it.
    assert nees_body(np.array([0.0]), np.array([[0.1, -0.2]]), cov)[0] == pytest.approx(2.0)
    corr = np.array([[0.04, 0.01, 0.01]])
    e = np.array([0.2, 0.1])
    want = e @ np.linalg.inv(np.array([[0.04, 0.01], [0.01, 0.01]])) @ e
    assert nees_body(np.array([math.pi / 2]), e[None, :], corr)[0] == pytest.approx(want)
    assert math.isnan(nees_body(np.array([0.0]), np.array([[0.1, 0.1]]), np.array([[0.0, 0.0, 0.0]]))[0])
    assert abs(NEES_TICK_BOUND_99 + 2 * math.log(0.01)) < 1e-4


def test_errors_on_every_tick_and_on_the_ticks_with_a_reading() -> None:
    acc = TargetErrors()
    pose = np.array([[0.0, 0.0, math.pi / 2]] * 3)
    target = np.array([[0.0, 2.0]] * 3)
    measured = np.array([[0.3, 2.0], [NAN, NAN], [0.0, 2.4]])  # no reading on the second tick
    estimate = np.array([[0.1, 2.0], [0.0, 2.3], [0.0, 2.0]])
    cov = np.array([[0.01, 0.0, 0.01], [NAN, NAN, NAN], [0.01, 0.0, 0.01]])
    acc.add(pose, target, measured, estimate, cov)
    s = acc.stats()
    assert s["measured_rms_m"] == pytest.approx(math.sqrt((0.09 + 0.16) / 2))
    assert s["ekf_rms_m"] == pytest.approx(math.sqrt((0.01 + 0.09 + 0.0) / 3))
    assert s["ekf_rms_seen_m"] == pytest.approx(math.sqrt(0.01 / 2))
    assert s["nees_ticks"] == 2  # the tick without a covariance has no NEES
    assert s["nees_mean"] == pytest.approx((1.0 + 0.0) / 2)
    assert s["nees_beyond_99"] == 0.0
    assert TargetErrors().stats() == dict.fromkeys(s, None) | {"nees_ticks": 0}
