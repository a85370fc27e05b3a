"""Every follower's formation error of a tick at once, and their sums over
the run: what world.metrics keeps follower by follower (FollowerMetrics.add
and the error windows), as numpy arrays, for swarms of hundreds.

The same numbers, bit for bit: the cosines, sines and distances come from
math (numpy's may differ in the last bit), and the rest is numpy's
elementwise + - * / and comparisons in the order of the per-follower code,
each exact in IEEE arithmetic as Python's is. A maximum keeps the old value
unless the new one is larger, as Python's max(old, new) does.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from formation_swarm.world.kinematics import Pose
from formation_swarm.world.setup import WorldSetup

# One robot's state in a snapshot: pose, wheel command (left, right m/s), formation code.
State = tuple[Pose, tuple[float, float], int]


def _larger(old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """max(old, new) of every element, as Python takes it: old unless new > old."""
    return np.where(new > old, new, old)


class FormationErrors:
    """The followers' formation errors, tick by tick, as arrays in the order of
    ``setup.follower_ids``."""

    def __init__(self, setup: WorldSetup, window_ticks: int, turn_rate_rps: float) -> None:
        self.setup = setup
        self.rids = list(setup.follower_ids)
        self.window_ticks = window_ticks
        self.turn_rate_rps = turn_rate_rps
        n = len(self.rids)
        self.samples = 0
        # FollowerMetrics' sums, one element per follower.
        self.sums = {
            name: np.zeros(n)
            for name in (
                "sum_sq_m2",
                "max_m",
                "turn_sum_sq_m2",
                "turn_max_m",
                "turn_along_sum_m",
                "max_lag_m",
                "max_ahead_m",
            )
        }
        self.turn_samples = np.zeros(n, dtype=np.int64)
        # Each window of window_ticks: [sum of errors, largest error, ticks].
        self.windows: list[list] = []
        self._ids: list[int] = []  # the snapshot's robots, in its order, when the rows below were made
        self._row: dict[int, int] = {}  # each robot's row in the snapshot
        self._rows: np.ndarray = np.zeros(0, np.int64)  # each follower's row in the snapshot
        self._slots: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # code: reference rows, offsets
        self._in_id_order = False  # whether the snapshot's robots come by increasing id
        self._poses = np.zeros((0, 3))  # the last snapshot's poses, one row per robot

    def _slot_arrays(self, code: int, row: dict[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each follower's reference row and slot offset (x, y) in formation ``code``."""
        got = self._slots.get(code)
        if got is None:
            slots = [self.setup.formation_by_code(code).slots[rid] for rid in self.rids]
            got = (
                np.array([row[s.reference] for s in slots], dtype=np.int64),
                np.array([float(s.offset[0]) for s in slots]),
                np.array([float(s.offset[1]) for s in slots]),
            )
            self._slots[code] = got
        return got

    def add(self, snap: dict[int, State]) -> np.ndarray:
        """The formation errors (m) of one tick's snapshot, one per follower,
        added to the sums (as FollowerMetrics.add and the windows would)."""
        ids = list(snap)
        poses, commands, codes = zip(*snap.values(), strict=True)
        if ids != self._ids:
            self._ids, self._row, self._slots = ids, {rid: k for k, rid in enumerate(ids)}, {}
            self._rows = np.array([self._row[r] for r in self.rids], np.int64)
            self._in_id_order = ids == sorted(ids)
        n_all = len(ids)
        state = np.fromiter(itertools.chain.from_iterable(poses), dtype=float, count=3 * n_all).reshape(-1, 3)
        self._poses = state
        wheels = np.fromiter(itertools.chain.from_iterable(commands), dtype=float, count=2 * n_all).reshape(-1, 2)
        followers = self._rows
        code = np.fromiter(codes, dtype=np.int64, count=n_all)[followers]
        refs, ox, oy = self._slot_arrays(int(code[0]), self._row)
        if (code != code[0]).any():  # followers in several formations (one changing over, say)
            refs, ox, oy = refs.copy(), ox.copy(), oy.copy()
            for other in np.unique(code[code != code[0]]).tolist():
                at = code == other
                r2, ox2, oy2 = self._slot_arrays(other, self._row)
                refs[at], ox[at], oy[at] = r2[at], ox2[at], oy2[at]
        heading = state[:, 2].tolist()
        cos_all = np.fromiter(map(math.cos, heading), dtype=float, count=n_all)
        sin_all = np.fromiter(map(math.sin, heading), dtype=float, count=n_all)
        c, s = cos_all[refs], sin_all[refs]
        ref = state[refs]
        # from_body_frame's target, then metrics' error and its part along the reference's heading.
        ex = ref[:, 0] + ox * s + oy * c - state[followers, 0]
        ey = ref[:, 1] - ox * c + oy * s - state[followers, 1]
        along = ex * c + ey * s
        turning = (np.abs(wheels[refs, 1] - wheels[refs, 0]) / self.setup.width_m) >= self.turn_rate_rps
        err = np.fromiter(map(math.hypot, ex.tolist(), ey.tolist()), dtype=float, count=len(followers))
        self._sum(err, along, turning)
        return err

    def pose_bytes(self) -> bytes | None:
        """The last snapshot's poses as little-endian doubles (x, y, theta), robot
        by robot in increasing id, or None if its robots came in another order."""
        return self._poses.astype("<f8", copy=False).tobytes() if self._in_id_order else None

    def _sum(self, err: np.ndarray, along: np.ndarray, turning: np.ndarray) -> None:
        m = self.sums
        sq = err * err
        m["sum_sq_m2"] += sq
        m["max_m"] = _larger(m["max_m"], err)
        m["max_lag_m"] = _larger(m["max_lag_m"], along)
        m["max_ahead_m"] = _larger(m["max_ahead_m"], -along)
        if turning.any():
            m["turn_sum_sq_m2"][turning] += sq[turning]
            m["turn_max_m"][turning] = _larger(m["turn_max_m"][turning], err[turning])
            m["turn_along_sum_m"][turning] += along[turning]
            self.turn_samples += turning
        if self.samples % self.window_ticks == 0:
            self.windows.append([np.zeros(len(err)), np.zeros(len(err)), 0])
        w = self.windows[-1]
        w[0], w[1], w[2] = w[0] + err, _larger(w[1], err), w[2] + 1
        self.samples += 1

    def write(self, followers: dict) -> None:
        """Set each follower's FollowerMetrics sums to the arrays' (Python floats)."""
        columns = {name: a.tolist() for name, a in self.sums.items()}
        turns = self.turn_samples.tolist()
        for k, rid in enumerate(self.rids):
            f = followers[rid]
            for name, values in columns.items():
                setattr(f, name, values[k])
            f.samples, f.turn_samples = self.samples, turns[k]

    def error_windows(self) -> tuple[dict[str, list[float]], dict[str, list[float]]]:
        """Per follower (by str id), the mean and the largest error of each window, rounded to 0.1 mm."""
        if not self.windows:
            return {str(r): [] for r in self.rids}, {str(r): [] for r in self.rids}
        means = np.array([w[0] / w[2] for w in self.windows]).T.tolist()
        largest = np.array([w[1] for w in self.windows]).T.tolist()
        mean_m = {str(r): [round(v, 4) for v in vs] for r, vs in zip(self.rids, means, strict=True)}
        max_m = {str(r): [round(v, 4) for v in vs] for r, vs in zip(self.rids, largest, strict=True)}
        return mean_m, max_m
