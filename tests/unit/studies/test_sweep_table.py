"""The table a sweep ends with: per combination, its runs and the mean and
95% half-width of the main metrics."""

from __future__ import annotations

from formation_swarm.studies.tables import summary_table


def _row(label: str, seed: int, **metrics: float) -> dict[str, object]:
    return {"combination": label, "seed": seed, "run": f"{label}-{seed}", **metrics}


def test_a_line_per_combination_with_each_follower_s_rms() -> None:
    rows = [_row("links.obs_drop=0", s, r2_rms_m=0.5 + 0.1 * s, r3_rms_m=1.0, min_distance_m=1.5) for s in (0, 1)]
    rows.append(_row("links.obs_drop=0.3", 0, r2_rms_m=0.9, r3_rms_m=1.2, min_distance_m=1.4))
    head, first, second = summary_table(rows).splitlines()
    assert "R2 RMS m" in head
    assert "min distance m" in head
    # Two seeds: mean 0.55, half-width t(1) 12.706 x 0.0707 / sqrt(2) = 0.635.
    assert first.split()[:5] == ["links.obs_drop=0", "2", "0.550", "±", "0.635"]
    assert second.split()[:4] == ["links.obs_drop=0.3", "1", "0.900", "1.200"]  # one seed: no interval


def test_many_followers_give_their_median_and_the_worst() -> None:
    rows = [_row("", 0, **{f"r{i}_rms_m": 0.1 * i for i in range(2, 12)})]
    head, line = summary_table(rows).splitlines()
    assert "median of 10" in head
    assert line.split()[:5] == ["as", "shipped", "1", "0.650", "R11"]
