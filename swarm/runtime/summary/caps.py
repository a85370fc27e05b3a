"""What keeps ``summary.json``'s size independent of the run's length: the
lists that grow with it are capped, and the summary states each cap.

``error_windows``
    at most MAX_WINDOWS windows per follower: a longer run's are merged
    into wider ones (``window_s`` a whole multiple of the world's, the mean
    of the means, the largest of the largest), ``windows_at_most`` says the
    cap. The faults' recoveries are taken before, from the world's own.
``formation_events``
    the first MAX_FORMATION_EVENTS, ``formation_events_total`` counts them all.
``parts``
    the world's part without its ``error_windows`` (the summary's own).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

MAX_WINDOWS = 300  # per follower: 5 minutes of 1 s windows
MAX_FORMATION_EVENTS = 1000


def cap(out: dict[str, Any]) -> dict[str, Any]:
    """``out`` (a summary being built) with its growing lists capped, in place."""
    out["error_windows"] = merged_windows(out.get("error_windows"))
    events = out.get("formation_events")
    if isinstance(events, list):
        out["formation_events_total"] = len(events)
        out["formation_events_at_most"] = MAX_FORMATION_EVENTS
        del events[MAX_FORMATION_EVENTS:]
    parts = out.get("parts")
    if isinstance(parts, dict) and isinstance(parts.get("world"), Mapping) and "error_windows" in parts["world"]:
        parts["world"] = {k: v for k, v in parts["world"].items() if k != "error_windows"}
    return out


def merged_windows(windows: Any, at_most: int = MAX_WINDOWS) -> Any:
    """The world's ``error_windows`` with at most ``at_most`` windows per
    follower (whole groups of k merged; the last group may be shorter)."""
    if not isinstance(windows, Mapping) or not isinstance(windows.get("window_s"), int | float):
        return windows
    means, maxes = windows.get("mean_m"), windows.get("max_m")
    if not isinstance(means, Mapping) or not isinstance(maxes, Mapping):
        return windows
    longest = max((len(v) for v in means.values() if isinstance(v, list)), default=0)
    k = max(1, math.ceil(longest / at_most))
    out = {**windows, "window_s": windows["window_s"] * k, "windows_at_most": at_most}
    if k == 1:
        return out
    out["mean_m"] = {rid: _groups(v, k, _mean) for rid, v in means.items()}
    out["max_m"] = {rid: _groups(v, k, _largest) for rid, v in maxes.items()}
    return out


def _groups(values: Any, k: int, merge: Any) -> Any:
    if not isinstance(values, list):
        return values
    return [merge(values[i : i + k]) for i in range(0, len(values), k)]


def _mean(group: list[Any]) -> float | None:
    nums = [v for v in group if isinstance(v, int | float)]
    return round(sum(nums) / len(nums), 4) if nums else None


def _largest(group: list[Any]) -> float | None:
    nums = [v for v in group if isinstance(v, int | float)]
    return max(nums) if nums else None
