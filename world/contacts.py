"""Who touches whom: collisions between robots and with obstacles, and the
closest two robots came, tick by tick. No I/O: the engine's metrics feed it
the poses of every tick they record.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from formation_swarm.world.camera import pose_array
from formation_swarm.world.grid import ALL_PAIRS_MAX, near_pairs
from formation_swarm.world.kinematics import Pose
from formation_swarm.world.setup import Obstacle

# Contacts listed in the summary with their tick and who touched whom (all are
# counted): enough to find the first ones; a 200-robot swarm that folds has hundreds.
CONTACTS_LISTED = 50
# Relative and absolute slack of numpy's distances, in m: far above the few ulps
# numpy's hypot and math's can differ by, far below any distance that matters.
SLACK = 1e-9
# Up to this many robots every pair is measured with math.hypot: numpy's fixed
# cost per call is dearer than the pairs it would spare.
SCALAR_MAX = 4
# The candidates' radius until a pair has come closer (m): any swarm dense
# enough to matter has a pair within it.
FIRST_RADIUS_M = 10.0


@dataclass
class Contacts:
    """A contact starts when two robots (or a robot and an obstacle) come
    closer than touching; it is counted once, however long it lasts."""

    diameter_m: float
    obstacles: Sequence[Obstacle]
    dt_s: float
    min_distance_m: float = math.inf
    collisions: int = 0
    obstacle_collisions: int = 0
    # The first CONTACTS_LISTED contacts counted: when, and who touched whom or what.
    listed: list[dict[str, object]] = field(default_factory=list)
    touching: set[tuple[int, int]] = field(default_factory=set)  # the last tick's; an obstacle is -1 - its index
    _pair_index: tuple[np.ndarray, np.ndarray] = field(default=(np.zeros(0, int), np.zeros(0, int)))

    def measure(self, poses: dict[int, Pose], tick: int) -> None:
        """Collisions (robot pairs, robots and obstacles) and the minimum distance
        of tick ``tick``. numpy measures the candidate pairs at once; the pairs
        it finds near the minimum or near touching (within SLACK) are measured
        again with math.hypot, which decides, as the pair loop did.

        The candidates are the pairs a grid (world.grid) finds within the
        smallest distance seen so far (or touching, if wider): a closer pair
        lowers the minimum, a farther one cannot. Only while no pair has come
        that close (the first tick) may every pair be measured."""
        ids = sorted(poses)
        if len(ids) <= SCALAR_MAX:
            self._by_pairs(ids, poses, tick)
            return
        xy = pose_array(poses, ids)[:, :2]
        slack, diameter = SLACK, self.diameter_m
        touching: set[tuple[int, int]] = set()
        radius = max(diameter * (1.0 + slack) + slack, min(self.min_distance_m, FIRST_RADIUS_M))
        if len(ids) ** 2 <= ALL_PAIRS_MAX:  # a few: every pair, without the grid's work
            ia, ib = self._pairs(len(ids))
        else:
            ia, ib = near_pairs(xy, xy, radius)
            keep = np.flatnonzero(ia < ib)
            ia, ib = ia[keep], ib[keep]
        d = np.hypot(xy[ia, 0] - xy[ib, 0], xy[ia, 1] - xy[ib, 1])
        if (not d.size or d.min() > radius) and self.min_distance_m > radius:
            ia, ib = self._pairs(len(ids))  # none that close: the minimum may be farther still
            d = np.hypot(xy[ia, 0] - xy[ib, 0], xy[ia, 1] - xy[ib, 1])
        if d.size:
            near = (d <= d.min() * (1.0 + slack) + slack) | (d < diameter * (1.0 + slack) + slack)
            for k in np.flatnonzero(near).tolist():
                a, b = ids[ia[k]], ids[ib[k]]
                pa, pb = poses[a], poses[b]
                dist = math.hypot(pa.x_m - pb.x_m, pa.y_m - pb.y_m)
                self.min_distance_m = min(self.min_distance_m, dist)
                if dist < diameter:
                    touching.add((a, b))
        for k, ob in enumerate(self.obstacles):
            reach = ob.radius_m + 0.5 * diameter
            d = np.hypot(xy[:, 0] - ob.x_m, xy[:, 1] - ob.y_m)
            for i in np.flatnonzero(d < reach * (1.0 + slack) + slack).tolist():
                p = poses[ids[i]]
                if math.hypot(p.x_m - ob.x_m, p.y_m - ob.y_m) < reach:
                    touching.add((ids[i], -1 - k))
        self._touched(touching, tick)

    def _by_pairs(self, ids: list[int], poses: dict[int, Pose], tick: int) -> None:
        """:meth:`measure` for a few robots: every pair measured with math.hypot,
        which decides all the same (numpy's fixed cost per call is dearer here
        than the pairs it would spare)."""
        diameter = self.diameter_m
        touching: set[tuple[int, int]] = set()
        least = self.min_distance_m
        for n, a in enumerate(ids):
            xa, ya = poses[a][0], poses[a][1]
            for b in ids[n + 1 :]:
                dist = math.hypot(xa - poses[b][0], ya - poses[b][1])
                least = min(least, dist)
                if dist < diameter:
                    touching.add((a, b))
            for k, ob in enumerate(self.obstacles):
                if math.hypot(xa - ob.x_m, ya - ob.y_m) < ob.radius_m + 0.5 * diameter:
                    touching.add((a, -1 - k))
        self.min_distance_m = least
        self._touched(touching, tick)

    def _touched(self, touching: set[tuple[int, int]], tick: int) -> None:
        """The contacts of one tick: those that are new are counted, and the
        first CONTACTS_LISTED listed."""
        new = touching - self.touching
        self.collisions += sum(1 for _, b in new if b > 0)
        self.obstacle_collisions += sum(1 for _, b in new if b < 0)
        self.touching = touching
        if new and len(self.listed) < CONTACTS_LISTED:
            for a, b in sorted(new, key=lambda pair: (pair[0], -pair[1] if pair[1] < 0 else pair[1])):
                what: dict[str, object] = {"robots": [a, b]} if b > 0 else {"robot": a, "obstacle": -1 - b}
                self.listed.append({"tick": tick, "time_s": round(tick * self.dt_s, 6), **what})
            del self.listed[CONTACTS_LISTED:]

    def _pairs(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Row and column of every pair i < j of ``n`` robots (cached: n rarely changes)."""
        if self._pair_index[0].size != n * (n - 1) // 2:
            self._pair_index = np.triu_indices(n, 1)
        return self._pair_index
