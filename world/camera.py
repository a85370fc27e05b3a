"""Simulated pan-tilt camera: what a robot sees of the other robots' markers.

Each robot carries a unique marker at ``marker_offset_m`` behind its centre on
its longitudinal axis (paper section 2.1, distance d). A camera reports, for
every marker inside its field of view and range, the marker's distance
rho_r (m), the bearing beta (rad, from the camera robot's heading, positive to
its right) and the marked robot's orientation relative to the observer phi
(rad, CCW positive), each with independent Gaussian noise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from formation_swarm.common.checks import non_negative, positive
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


class CameraFrame:
    """Every camera of one frame at once: :meth:`observe` gives what
    :func:`observe` gives, bit for bit, for any observer of ``poses``.

    Which markers a camera may see is decided for every pair of robots at
    once with numpy, with a small margin: numpy's ``hypot`` and ``arctan2``
    can differ from :mod:`math`'s in the last bit. Each marker that passes is
    then read and decided with the same scalar code as :func:`observe`, and
    each observer's noise is drawn in one call, three numbers per other robot
    in id order, the very stream of three draws per robot.

    Up to ``SCALAR_MAX`` robots there is no pre-selection: every marker is
    read and decided by that scalar code. numpy's fixed cost per call made
    the pre-selection dearer than what it saves at a few robots (three: 15 us
    a frame for 4 readings of 2 us each), and the decisions are the same.
    """

    # Relative and absolute slack of the numpy pre-selection, in m and rad: far
    # above the few ulps numpy and math can differ by, far below any distance
    # that matters.
    SLACK = 1e-9
    SCALAR_MAX = 4

    def __init__(self, poses: Mapping[int, Pose], params: CameraParams) -> None:
        self.poses = poses
        self.params = params
        self.ids = sorted(poses)
        self._row = {rid: i for i, rid in enumerate(self.ids)}
        # By row, once a frame: each marker's world position (marker_position) and
        # each heading's cosine and sine (to_body_frame's), the same numbers.
        d = params.marker_offset_m
        rows = [poses[rid] for rid in self.ids]
        self._headings = [p[2] for p in rows]
        self._markers = [marker_position(p, d) for p in rows]
        self._trig = [(math.cos(p[2]), math.sin(p[2])) for p in rows]
        self._maybe: np.ndarray | None = None  # None: every other robot's marker is read
        if len(self.ids) <= self.SCALAR_MAX:
            return
        a = np.array([poses[i] for i in self.ids], dtype=float).reshape(-1, 3)
        x, y, th = a[:, 0], a[:, 1], a[:, 2]
        c, s = np.cos(th), np.sin(th)
        d = params.marker_offset_m
        # Row: observer; column: the marker of the robot seen (to_body_frame).
        dx = (x - d * c)[None, :] - x[:, None]
        dy = (y - d * s)[None, :] - y[:, None]
        xb = dx * s[:, None] - dy * c[:, None]
        yb = dx * c[:, None] + dy * s[:, None]
        slack = self.SLACK
        maybe = np.hypot(xb, yb) <= params.range_m * (1.0 + slack) + slack
        half_fov = 0.5 * params.fov_rad
        if half_fov < math.pi:  # else every bearing is within the field of view
            maybe &= np.abs(np.arctan2(xb, yb)) <= half_fov * (1.0 + slack) + slack
        np.fill_diagonal(maybe, False)
        self._maybe = maybe

    def observe(self, observer_id: int, rng: np.random.Generator) -> list[MarkerReading]:
        params = self.params
        i = self._row[observer_id]
        # Three draws per other robot, in view or not (the stream); only those of
        # the markers in view are read, as Python floats (item: the same numbers).
        noise = rng.standard_normal(3 * (len(self.ids) - 1)).item
        observer = self.poses[observer_id]
        half_fov = 0.5 * params.fov_rad
        out: list[MarkerReading] = []
        maybe = self._maybe
        candidates = range(len(self.ids)) if maybe is None else np.flatnonzero(maybe[i]).tolist()
        ox, oy, oth = observer[0], observer[1], observer[2]
        c, s = self._trig[i]
        markers, headings = self._markers, self._headings
        for j in candidates:
            if j == i:
                continue
            k = 3 * (j if j < i else j - 1)  # the observer itself draws nothing
            # true_reading, written out on the frame's markers and trigonometry.
            dx = markers[j][0] - ox
            dy = markers[j][1] - oy
            xb, yb = dx * s - dy * c, dx * c + dy * s
            rho, beta = math.hypot(xb, yb), math.atan2(xb, yb)
            if rho > params.range_m or abs(beta) > half_fov:
                continue
            phi = wrap_angle(headings[j] - oth)
            out.append(
                MarkerReading(
                    self.ids[j],
                    max(0.0, rho + params.sigma_rho_m * noise(k)),
                    wrap_angle(phi + params.sigma_phi_rad * noise(k + 1)),
                    wrap_angle(beta + params.sigma_beta_rad * noise(k + 2)),
                )
            )
        return out


def observe(
    observer_id: int,
    poses: dict[int, Pose],
    params: CameraParams,
    rng: np.random.Generator,
) -> list[MarkerReading]:
    """Every marker ``observer_id``'s camera sees this frame, sorted by robot id.

    Visibility is decided on the true reading; noise is drawn afterwards, three
    draws per robot in id order, visible or not, so that the random stream does
    not depend on what happens to be in view.
    """
    observer = poses[observer_id]
    half_fov = 0.5 * params.fov_rad
    out: list[MarkerReading] = []
    for rid in sorted(poses):
        if rid == observer_id:
            continue
        n_rho, n_phi, n_beta = rng.standard_normal(3).tolist()
        rho, phi, beta = true_reading(observer, poses[rid], params.marker_offset_m)
        if rho > params.range_m or abs(beta) > half_fov:
            continue
        out.append(
            MarkerReading(
                rid,
                max(0.0, rho + params.sigma_rho_m * n_rho),
                wrap_angle(phi + params.sigma_phi_rad * n_phi),
                wrap_angle(beta + params.sigma_beta_rad * n_beta),
            )
        )
    return out
