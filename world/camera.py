"""Simulated pan-tilt camera: what a robot sees of the other robots' markers.

Each robot carries a unique marker at ``marker_offset_m`` behind its centre on
its longitudinal axis (paper section 2.1, distance d). A camera reports, for
every marker inside its field of view and range, the marker's distance
rho_r (m), the bearing beta (rad, from the camera robot's heading, positive to
its right) and the marked robot's orientation relative to the observer phi
(rad, CCW positive), each with independent Gaussian noise: three draws from
the observer's own generator per marker in view, in robot-id order.

Drawing for the markers in view only keeps a frame's cost in proportion to
what the cameras see (a dozen markers each in a line of robots 1.5 m
apart): three draws for every other robot, in view or not, cost O(N^2) a
frame, 30 ms at 1,000 robots. The stream thus follows what is in view,
which the true poses decide: a run is reproduced draw for draw all the same,
and where every marker is in view (the paper's three robots) it is the
stream of three draws per other robot it always was.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from formation_swarm.common.checks import non_negative, positive
from formation_swarm.world.grid import near_pairs
from formation_swarm.world.kinematics import Pose, to_body_frame, wrap_angle


class MarkerReading(NamedTuple):
    """One marker seen by one camera in one frame."""

    robot_id: int
    rho_m: float
    phi_rad: float
    beta_rad: float


@dataclass(frozen=True)
class CameraParams:
    fov_rad: float = 2.0 * math.pi  # pan-tilt camera (paper sec. 1): all around
    range_m: float = 10.0
    sigma_rho_m: float = 0.05
    sigma_phi_rad: float = math.radians(3.0)
    sigma_beta_rad: float = math.radians(1.5)
    marker_offset_m: float = 0.1

    def __post_init__(self) -> None:
        fov = positive("fov_rad", self.fov_rad)
        if fov > 2.0 * math.pi:
            raise ValueError(f"fov_rad must be <= 2*pi, got {fov!r}")
        positive("range_m", self.range_m)
        non_negative("sigma_rho_m", self.sigma_rho_m)
        non_negative("sigma_phi_rad", self.sigma_phi_rad)
        non_negative("sigma_beta_rad", self.sigma_beta_rad)
        non_negative("marker_offset_m", self.marker_offset_m)


def marker_position(pose: Pose, marker_offset_m: float) -> tuple[float, float]:
    """World position of a robot's marker, ``marker_offset_m`` behind its centre."""
    return (
        pose[0] - marker_offset_m * math.cos(pose[2]),
        pose[1] - marker_offset_m * math.sin(pose[2]),
    )


def true_reading(observer: Pose, target: Pose, marker_offset_m: float) -> tuple[float, float, float]:
    """Noise-free (rho_r, phi, beta) of ``target``'s marker seen from ``observer``."""
    mx, my = marker_position(target, marker_offset_m)
    xb, yb = to_body_frame(observer, mx, my)
    return math.hypot(xb, yb), wrap_angle(target[2] - observer[2]), math.atan2(xb, yb)


Reading = tuple[int, float, float, float]  # a MarkerReading as a plain tuple: robot_id, rho_m, phi_rad, beta_rad


def _noisy(seen: list[Reading], params: CameraParams, rng: np.random.Generator) -> list[MarkerReading]:
    """``seen``'s true readings with noise: three draws per reading, in order."""
    if not seen:
        return []
    noise = rng.standard_normal(3 * len(seen)).tolist()
    return [
        MarkerReading(
            rid,
            max(0.0, rho + params.sigma_rho_m * noise[3 * k]),
            wrap_angle(phi + params.sigma_phi_rad * noise[3 * k + 1]),
            wrap_angle(beta + params.sigma_beta_rad * noise[3 * k + 2]),
        )
        for k, (rid, rho, phi, beta) in enumerate(seen)
    ]


def _in_view(observer_id: int, poses: Mapping[int, Pose], params: CameraParams) -> list[Reading]:
    """The true readings of every marker in ``observer_id``'s view, by robot id."""
    observer = poses[observer_id]
    half_fov = 0.5 * params.fov_rad
    seen = []
    for rid in sorted(poses):
        if rid == observer_id:
            continue
        rho, phi, beta = true_reading(observer, poses[rid], params.marker_offset_m)
        if rho <= params.range_m and abs(beta) <= half_fov:
            seen.append((rid, rho, phi, beta))
    return seen


def observe(
    observer_id: int,
    poses: Mapping[int, Pose],
    params: CameraParams,
    rng: np.random.Generator,
) -> list[MarkerReading]:
    """Every marker ``observer_id``'s camera sees this frame, sorted by robot id.

    Visibility is decided on the true reading; noise is drawn afterwards,
    three draws per marker in view, in id order. Pair by pair, with
    :mod:`math`: the reference :class:`CameraFrame` follows for every camera
    at once.
    """
    return _noisy(_in_view(observer_id, poses, params), params, rng)


class CameraFrame:
    """Every camera of one frame at once: :meth:`observe_many` gives what
    :func:`observe` gives for each observer of ``poses``: the same markers
    seen but at a distance or a bearing on the edge of the range or the view
    (within a few ulps), the same draws, the same numbers but maybe the last
    bit (below).

    Which markers each camera may see comes from a grid of cells as wide as
    the camera's range (world.grid): a robot is measured against the markers
    of its own and the adjacent cells only, so a frame costs O(N) for N
    robots spread out, not O(N^2). The candidates are measured with numpy,
    in the operations and the order of :func:`true_reading` but for the
    distance, sqrt(x^2 + y^2), and the bearing, numpy's arctan2 (math's hypot
    and atan2 may round the last bit otherwise: a Python call per reading
    costs as much as the rest of the frame), and the noise is applied to all
    of them at once.

    Up to ``SCALAR_MAX`` robots each camera is read pair by pair
    (:func:`observe`, bit for bit): numpy's fixed cost per call is dearer
    than a few pairs, and the paper's three-robot runs keep their numbers.
    """

    SCALAR_MAX = 4

    def __init__(self, poses: Mapping[int, Pose], params: CameraParams) -> None:
        self.poses = poses
        self.params = params
        self.ids = sorted(poses)
        self._row = {rid: i for i, rid in enumerate(self.ids)}
        # By observer row: (first, count) of its readings in the frame's arrays (_read).
        self._frame: tuple[np.ndarray, ...] | None = None

    def _read(self) -> tuple[np.ndarray, ...]:
        """Every true reading in view, by observer row then robot id: robot ids,
        rho, phi, beta, and each observer row's first reading and count."""
        if self._frame is not None:
            return self._frame
        params, d = self.params, self.params.marker_offset_m
        n = len(self.ids)
        pose = pose_array(self.poses, self.ids)
        x, y, th = pose[:, 0], pose[:, 1], pose[:, 2]
        # to_body_frame's and marker_position's cosines and sines: math's, once per robot.
        heading = th.tolist()
        c, s = np.array(list(map(math.cos, heading))), np.array(list(map(math.sin, heading)))
        mx, my = x - d * c, y - d * s
        i, j = near_pairs(pose[:, :2], np.column_stack((mx, my)), params.range_m)
        dx, dy = mx[j] - x[i], my[j] - y[i]
        xb = dx * s[i] - dy * c[i]
        yb = dx * c[i] + dy * s[i]
        rho = np.sqrt(xb * xb + yb * yb)
        keep = np.flatnonzero((rho <= params.range_m) & (i != j))
        keep = keep[np.argsort(i[keep] * n + j[keep])]  # by observer, then robot id (rows are in id order)
        i, j, xb, yb, rho = i[keep], j[keep], xb[keep], yb[keep], rho[keep]
        beta = np.arctan2(xb, yb)
        half_fov = 0.5 * params.fov_rad
        if half_fov < math.pi:  # else every bearing is within the field of view
            keep = np.flatnonzero(np.abs(beta) <= half_fov)
            i, j, rho, beta = i[keep], j[keep], rho[keep], beta[keep]
        phi = _wrap(th[j] - th[i])
        count = np.bincount(i, minlength=n)
        self._frame = (np.array(self.ids, dtype=np.int64)[j], rho, phi, beta, np.cumsum(count) - count, count)
        return self._frame

    def observe(self, observer_id: int, rng: np.random.Generator) -> list[MarkerReading]:
        """:func:`observe` of one observer."""
        return [MarkerReading(*m) for m in self.observe_many([(observer_id, rng)])[observer_id]]

    def observe_many(self, observers: Sequence[tuple[int, np.random.Generator]]) -> dict[int, list[Reading]]:
        """Each observer's readings (robot id, rho, phi, beta), its noise drawn
        from its generator: what :func:`observe` gives, as plain tuples."""
        seen = self.observe_arrays(observers)
        readings = list(zip(seen.ids.tolist(), seen.rho.tolist(), seen.phi.tolist(), seen.beta.tolist(), strict=True))
        out: dict[int, list[Reading]] = {}
        k = 0
        for (rid, _), m in zip(observers, seen.counts, strict=True):
            out[rid] = readings[k : k + m]
            k += m
        return out

    def observe_arrays(self, observers: Sequence[tuple[int, np.random.Generator]]) -> Seen:
        """:meth:`observe_many` as arrays: every observer's readings one after the other."""
        params = self.params
        if len(self.ids) <= self.SCALAR_MAX:
            each = [observe(rid, self.poses, params, rng) for rid, rng in observers]
            flat = np.array([m for seen in each for m in seen], dtype=float).reshape(-1, 4)
            counts = [len(seen) for seen in each]
            return Seen(flat[:, 0].astype(np.int64), flat[:, 1], flat[:, 2], flat[:, 3], counts)
        ids, rho, phi, beta, first, count = self._read()
        rows = np.array([self._row[rid] for rid, _ in observers], dtype=np.int64)
        n = count[rows]
        counts = n.tolist()
        total = int(n.sum())
        noise = np.empty((total, 3))
        k = 0
        for (_, rng), m in zip(observers, counts, strict=True):
            if m:  # into its place: the same draws as standard_normal(3 * m) gives
                rng.standard_normal(out=noise[k : k + m].reshape(-1))
                k += m
        # Every observer's readings, in observer order: each row's first ... first + count - 1.
        at = np.repeat(first[rows] - (np.cumsum(n) - n), n) + np.arange(total)
        return Seen(
            ids[at],
            np.maximum(0.0, rho[at] + params.sigma_rho_m * noise[:, 0]),
            _wrap(phi[at] + params.sigma_phi_rad * noise[:, 1]),
            _wrap(beta[at] + params.sigma_beta_rad * noise[:, 2]),
            counts,
        )


class Seen(NamedTuple):
    """The readings of several cameras, one after the other: robot ids, rho_m,
    phi_rad, beta_rad (arrays), and how many each camera gave, in order."""

    ids: np.ndarray
    rho: np.ndarray
    phi: np.ndarray
    beta: np.ndarray
    counts: list[int]


def pose_array(poses: Mapping[int, Pose], ids: Sequence[int]) -> np.ndarray:
    """The poses of ``ids``, in order, as an (n, 3) array (fromiter: a sixth of np.array's time on tuples)."""
    flat = itertools.chain.from_iterable([poses[rid] for rid in ids])
    return np.fromiter(flat, dtype=float, count=3 * len(ids)).reshape(-1, 3)


def _wrap(angle_rad: np.ndarray) -> np.ndarray:
    """:func:`wrap_angle` of every element: numpy's % is Python's on floats (fmod, then the sign's fix)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi
