"""The recording's 1 s means, taken as the run goes, equal the report's moving average."""

from __future__ import annotations

import numpy as np

from formation_swarm.nodes.logger.running_mean import CentredMean
from formation_swarm.report.figures.series import moving_average


def test_fed_in_pieces_it_equals_the_report_s_centred_average_across_gaps() -> None:
    rng = np.random.default_rng(1)
    dt = 0.05
    ticks = np.unique(rng.integers(0, 400, 300))  # gaps: missing ticks, some of them runs
    t, v = ticks * dt, rng.normal(size=len(ticks))
    mean = CentredMean(1.0, dt)
    got_t: list[float] = []
    got_v: list[float] = []
    for i in range(0, len(t), 7):  # as sends come: a few ticks at a time
        a, b = mean.add(t[i : i + 7].tolist(), v[i : i + 7].tolist())
        got_t += a
        got_v += b
    a, b = mean.end()
    np.testing.assert_array_equal(np.array(got_t + a), t)
    np.testing.assert_allclose(np.array(got_v + b), moving_average(t, v, 1.0, dt), rtol=0, atol=1e-12)


def test_a_mean_is_given_half_a_window_late_and_an_old_sample_is_left_out() -> None:
    mean = CentredMean(1.0, 0.1)  # 10 samples: 5 before, 4 after
    times, _ = mean.add([0.1 * k for k in range(4)], [1.0] * 4)
    assert times == []  # sample 0 waits for 4 after it
    times, values = mean.add([0.4, 0.3], [6.0, 9.0])  # 0.3 again: left out
    assert times == [0.0]
    assert values == [2.0]  # (1 + 1 + 1 + 1 + 6) / 5
