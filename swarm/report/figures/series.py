"""A recorded series made ready to draw: its unbroken stretches, NaN across
its gaps, a moving average that takes none across one, robust axis limits
and the median over many followers. Numbers only, no drawing."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

Series = Any  # data.Series: .t (s) and .v, time-sorted

QUANTILE = 99.5  # robust axis limits: this percentile, with a margin
GAP_TICKS = 1.5  # a series with no row for longer than this many ticks has a gap: no line across it


def robust_top(arrays: Sequence[np.ndarray], floor: float = 0.0) -> tuple[float, float | None]:
    """An upper y limit that a few outliers do not blow out: the 99.5th
    percentile of all the values plus 15%, or their maximum plus 5% when that
    is not much larger. Also the maximum when it is cut off, else None."""
    vals = np.concatenate([np.asarray(a, dtype=float).ravel() for a in arrays]) if arrays else np.zeros(0)
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return max(floor, 1.0), None
    top, q = float(np.max(vals)), float(np.percentile(vals, QUANTILE))
    if top <= 1.5 * q or q <= 0.0:
        return max(floor, 1.05 * top if top > 0 else 1.0), None
    return max(floor, 1.15 * q), top


def stretches(t: np.ndarray, dt_s: float) -> list[slice]:
    """The unbroken stretches of a time series: a gap of more than GAP_TICKS
    ticks (an agent killed, frozen or restarted; a robot out of its camera's
    view) ends one."""
    breaks = np.flatnonzero(np.diff(t) > GAP_TICKS * dt_s) + 1
    edges = [0, *breaks.tolist(), len(t)]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def gapped(t: np.ndarray, v: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``t`` and ``v`` with a NaN between stretches, so that a line is not drawn across a gap."""
    parts = stretches(t, dt_s)
    if len(parts) <= 1:
        return t, v
    gap = np.full((1, *np.shape(v)[1:]), np.nan)
    ts, vs = [], []
    for k, sl in enumerate(parts):
        if k:
            ts.append(np.array([0.5 * (t[sl.start - 1] + t[sl.start])]))
            vs.append(gap)
        ts.append(t[sl])
        vs.append(v[sl])
    return np.concatenate(ts), np.concatenate(vs)


def moving_average(t: np.ndarray, v: np.ndarray, window_s: float, dt_s: float) -> np.ndarray:
    """Centred moving average over ``window_s`` (in ticks of ``dt_s``); shorter at
    the ends of each unbroken stretch, none of which averages across a gap."""
    n = max(1, int(round(window_s / dt_s)))
    if n <= 1 or len(v) < 2:
        return v.copy()
    out = np.empty(len(v))
    kernel = np.ones(n)
    for sl in stretches(t, dt_s):
        part = v[sl]
        if len(part) >= n:
            out[sl] = np.convolve(part, kernel, mode="same") / np.convolve(np.ones_like(part), kernel, mode="same")
        else:  # "same" gives the window's length then: take the part's own, centred as above
            lo = (n - 1) // 2
            kept = slice(lo, lo + len(part))
            out[sl] = np.convolve(part, kernel)[kept] / np.convolve(np.ones_like(part), kernel)[kept]
    return out


def median_over(series: Mapping[int, tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The median over the followers' (t, v) at each time of the longest one;
    a follower counts only within its own times (a killed one's ends early)."""
    grid = max((t for t, _ in series.values()), key=len)
    rows = np.full((len(series), len(grid)), np.nan)
    for k, (t, v) in enumerate(series.values()):
        inside = (grid >= t[0]) & (grid <= t[-1])
        rows[k, inside] = np.interp(grid[inside], t, v)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an instant no follower covers: NaN
        return grid, np.nanmedian(rows, axis=0)
