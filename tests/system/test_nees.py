"""The EKF's NEES as a run's summary carries it (world.metrics.TargetErrors):
the shipped filter stays under the 99% bound of a consistent filter's mean
NEES, a filter told a tenth of the process noise rises above it."""

from __future__ import annotations

import pytest
from scipy.stats import chi2

from formation_swarm.studies import engine_run

# Every process-noise density of the filter divided by 10 (its Q by 100): overconfident.
OVERCONFIDENT = {
    "controller.ekf.q_pos_m": 0.002,
    "controller.ekf.q_phi_rad": 0.002,
    "controller.ekf.q_speed_mps": 0.05,
    "controller.ekf.q_turn_rps": 0.05,
}


def _upper_99(ticks: int) -> float:
    """The 99% point of the mean of ``ticks`` chi-square(2) values: chi2(2 n) / n."""
    return float(chi2.ppf(0.99, 2 * ticks) / ticks)


@pytest.mark.slow
def test_an_overconfident_filter_rises_above_the_nees_bound_the_shipped_one_stays_under() -> None:
    shipped, _ = engine_run.run("fig9_ekf_noise", 0)
    planted, _ = engine_run.run("fig9_ekf_noise", 0, OVERCONFIDENT)
    ok = shipped["parts"]["logger"]["target_errors"]["2"]
    bad = planted["parts"]["logger"]["target_errors"]["2"]
    assert ok["nees_ticks"] == bad["nees_ticks"] == 880
    bound = _upper_99(880)
    assert bound == pytest.approx(2.160, abs=1e-3)
    assert ok["nees_mean"] == pytest.approx(1.614, abs=1e-3)
    assert ok["nees_mean"] < bound
    assert ok["nees_beyond_99"] < 0.01  # a consistent filter: 1% of ticks beyond chi2(2)'s 99% point
    assert bad["nees_mean"] == pytest.approx(4.114, abs=1e-3)
    assert bad["nees_mean"] > bound
    assert bad["nees_beyond_99"] > 0.1


@pytest.mark.slow
def test_the_engine_runs_target_errors_are_the_logged_lockstep_runs() -> None:
    """Seed 0 of fig9_ekf_noise as docs/results/claims.csv holds it (a lockstep run with its logger)."""
    summary, _ = engine_run.run("fig9_ekf_noise", 0)
    errors = summary["parts"]["logger"]["target_errors"]["2"]
    assert errors["measured_rms_m"] == pytest.approx(0.2340083771906369, rel=1e-12)
    assert errors["ekf_rms_m"] == pytest.approx(0.0965492346599799, rel=1e-12)
    assert errors["ekf_rms_seen_m"] == errors["ekf_rms_m"]  # no drops: a reading every tick
    assert summary["followers"]["2"]["rms_m"] == pytest.approx(0.7552026874776966, rel=1e-12)
