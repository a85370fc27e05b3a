"""The report's follower table carries the EKF's NEES from summary.json."""

from __future__ import annotations

from formation_swarm.report.markdown import _metrics_table


def test_the_follower_table_shows_mean_nees_and_the_share_beyond_the_99_percent_point() -> None:
    summary = {
        "ticks": 880,
        "followers": {"2": {"rms_m": 0.75, "max_m": 1.4}},
        "parts": {
            "logger": {"target_errors": {"2": {"ekf_rms_m": 0.0965, "nees_mean": 1.6144, "nees_beyond_99": 0.0057}}}
        },
    }
    head, _rule, row = _metrics_table(summary, [2])
    assert head.endswith("| EKF mean NEES (ticks beyond 9.21) |")
    assert row.endswith("| 0.097 | 1.61 (0.6%) |")
    no_nees = {**summary, "parts": {"logger": {"target_errors": {"2": {"ekf_rms_m": 0.1}}}}}
    assert _metrics_table(no_nees, [2])[2].endswith("| 0.100 | - |")
