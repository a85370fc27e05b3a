"""Which points lie near which: the candidate pairs of a range query, found
through a grid of square cells instead of every pair (numpy only).

A point of ``a`` and a point of ``b`` closer than ``radius_m`` always sit in
the same or in adjacent cells of side ``radius_m``: looking in those nine
cells finds every such pair, and a swarm of N robots spread over the plane
yields O(N) candidates instead of N^2. The caller measures the candidates
and decides; the grid only never leaves out a pair within the radius.
(scipy's cKDTree does this too, but scipy is not one of our dependencies.)
"""

from __future__ import annotations

import numpy as np

# Cells per row of the key: far more than any swarm spans (cells of 1 m over
# 2^20 m), and the keys of x and y stay apart in an int64.
_ROW = 1 << 21
# Up to this many pairs, every pair is a candidate: measuring them all costs less
# than the grid (about 50 robots among themselves).
ALL_PAIRS_MAX = 2500


def _cells(x: np.ndarray, y: np.ndarray, side: float, origin: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    return np.floor((x - origin[0]) / side).astype(np.int64), np.floor((y - origin[1]) / side).astype(np.int64)


def near_pairs(a: np.ndarray, b: np.ndarray, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``i`` of ``a`` and ``j`` of ``b`` (both (n, 2) arrays of x, y) of
    every pair in the same or adjacent cells of side ``radius_m``: a superset
    of the pairs closer than ``radius_m``, in no particular order."""
    if len(a) * len(b) <= ALL_PAIRS_MAX:  # few: every pair costs less than the grid's sorting
        return np.divmod(np.arange(len(a) * len(b)), len(b))
    # A slightly larger side: a pair at exactly the radius stays within adjacent cells.
    side = float(radius_m) * (1.0 + 1e-9) + 1e-9
    origin = (min(a[:, 0].min(), b[:, 0].min()), min(a[:, 1].min(), b[:, 1].min()))
    ax, ay = _cells(a[:, 0], a[:, 1], side, origin)
    bx, by = _cells(b[:, 0], b[:, 1], side, origin)
    if max(ax.max(), ay.max(), bx.max(), by.max()) >= _ROW - 2:  # spread too far for the key: every pair
        return np.divmod(np.arange(len(a) * len(b)), len(b))
    # Keyed row by row (y, then x): the three cells of a row around a point are
    # adjacent in key order, so three ranges of the sorted keys hold its nine cells.
    bkey = by * _ROW + bx
    order = np.argsort(bkey, kind="stable")  # stable: each cell's points in row order
    sorted_keys = bkey[order]
    akey = ay * _ROW + ax
    starts, counts = [], []
    for dy in (-1, 0, 1):
        lo = np.searchsorted(sorted_keys, akey + (dy * _ROW - 1), side="left")
        hi = np.searchsorted(sorted_keys, akey + (dy * _ROW + 1), side="right")
        starts.append(lo)
        counts.append(hi - lo)
    row = np.tile(np.arange(len(a)), 3)
    start, count = np.concatenate(starts), np.concatenate(counts)
    total = int(count.sum())
    # Expand each (row, start, count) into count candidates: start, start + 1, ...
    i = np.repeat(row, count)
    j = order[np.repeat(start - (np.cumsum(count) - count), count) + np.arange(total)]
    return i, j
