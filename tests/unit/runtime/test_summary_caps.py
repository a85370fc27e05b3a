"""summary.json's size does not grow with the run's length: its error
windows are merged beyond a cap, its formation events cut at one, each cap
stated in the summary."""

from __future__ import annotations

import json

from formation_swarm.runtime.summary import caps


def _summary(seconds: int, followers: int = 3) -> dict[str, object]:
    means = {str(r): [0.01 * (i % 7) for i in range(seconds)] for r in range(2, 2 + followers)}
    maxes = {str(r): [float(i) for i in range(seconds)] for r in range(2, 2 + followers)}
    windows = {"window_s": 1.0, "mean_m": means, "max_m": maxes}
    events = [{"tick": i, "time_s": i * 0.05, "robot": 2, "formation": "line"} for i in range(seconds * 2)]
    return {"error_windows": windows, "formation_events": events, "parts": {"world": {"error_windows": windows}}}


def test_an_hour_s_summary_is_the_size_of_ten_minutes() -> None:
    ten, hour = (json.dumps(caps.cap(_summary(s))) for s in (600, 3600))
    assert abs(len(hour) - len(ten)) < 0.05 * len(ten)
    capped = caps.cap(_summary(3600))
    w = capped["error_windows"]
    assert (w["window_s"], w["windows_at_most"], len(w["mean_m"]["2"])) == (12.0, 300, 300)
    assert w["max_m"]["2"][:2] == [11.0, 23.0]  # the largest of each 12 windows
    assert w["mean_m"]["2"][0] == round(sum(0.01 * (i % 7) for i in range(12)) / 12, 4)
    assert (len(capped["formation_events"]), capped["formation_events_total"]) == (1000, 7200)
    assert capped["formation_events_at_most"] == 1000
    assert "error_windows" not in capped["parts"]["world"]


def test_a_short_run_keeps_its_windows_and_says_the_cap() -> None:
    w = caps.merged_windows(_summary(56)["error_windows"])
    assert (w["window_s"], w["windows_at_most"], len(w["max_m"]["3"])) == (1.0, 300, 56)
    assert caps.merged_windows(None) is None
