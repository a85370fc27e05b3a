"""The run's figures, taken tick by tick from snapshots of the robots' state:
each follower's formation error (overall, in turns, in windows of time, up
to its first stop), the recoveries after a return, the contacts and a digest
of the trajectories. No I/O: the engine hands it one snapshot per tick.
And a follower's target estimate against the truth (TargetErrors: its
errors and the EKF's NEES), batch by batch, for whoever has its telemetry.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from formation_swarm.world.contacts import Contacts
from formation_swarm.world.formation_errors import FormationErrors
from formation_swarm.world.kinematics import Pose, from_body_frame
from formation_swarm.world.leader_track import LeaderTrack
from formation_swarm.world.recovery import Recovery
from formation_swarm.world.setup import WorldSetup

# A reference turning at least this fast (from its wheel commands) is "in a turn"
# for the metrics; the paper's path turns at 0.25 rad/s, pure pursuit on a
# straight line stays well under this.
TURN_RATE_RPS = 0.1
# The formation error over time, for recoveries: each follower's mean and
# largest error in every window of this many seconds (rounded to whole ticks).
# A second smooths the camera noise that a follower of a follower amplifies
# (fig11's robot 3: 10-35% of its ticks above 0.5 m in steady flight).
ERROR_WINDOW_S = 1.0
# From this many followers on, their errors are taken all at once (world.formation_errors,
# the same numbers): below, numpy's fixed cost per call is dearer than the loop.
ERRORS_AT_ONCE_FROM = 24

# One robot's state in a snapshot: pose, wheel command (left, right m/s), formation code.
Snapshot = dict[int, tuple[Pose, tuple[float, float], int]]

# FollowerMetrics.as_dict's metrics (None for a follower that never acquired its reference).
METRICS = (
    "rms_m",
    "max_m",
    "turn_rms_m",
    "straight_rms_m",
    "turn_max_m",
    "turn_samples",
    "turn_mean_lag_m",
    "max_lag_m",
    "max_ahead_m",
)


def target_in(setup: WorldSetup, rid: int, formation: int, poses: Mapping[int, Pose]) -> tuple[float, float]:
    """Follower ``rid``'s true virtual target in ``formation`` among ``poses`` (eq. 2)."""
    slot = setup.formation_by_code(formation).slots[rid]
    return from_body_frame(poses[slot.reference], slot.offset[0], slot.offset[1])


@dataclass
class FollowerMetrics:
    """Formation error of one follower: overall, and split by whether its reference
    is turning (|w| >= TURN_RATE_RPS) or going straight. ``along`` is the error's
    component along the reference's heading: > 0 the follower is behind its
    target (lags), < 0 it is ahead of it (overshoots)."""

    sum_sq_m2: float = 0.0
    max_m: float = 0.0
    samples: int = 0
    turn_sum_sq_m2: float = 0.0
    turn_max_m: float = 0.0
    turn_samples: int = 0
    turn_along_sum_m: float = 0.0
    max_lag_m: float = 0.0
    max_ahead_m: float = 0.0
    frames: int = 0  # camera frames taken for it (WorldEngine.observation())
    seen_ticks: int = 0  # of those, the frames that showed its reference (faults applied)

    def add(self, err_m: float, along_m: float = 0.0, turning: bool = False) -> None:
        self.sum_sq_m2 += err_m * err_m
        self.max_m = max(self.max_m, err_m)
        self.samples += 1
        self.max_lag_m = max(self.max_lag_m, along_m)
        self.max_ahead_m = max(self.max_ahead_m, -along_m)
        if turning:
            self.turn_sum_sq_m2 += err_m * err_m
            self.turn_max_m = max(self.turn_max_m, err_m)
            self.turn_samples += 1
            self.turn_along_sum_m += along_m

    def rms_m(self) -> float:
        return math.sqrt(self.sum_sq_m2 / self.samples) if self.samples else math.nan

    def as_dict(self) -> dict[str, float | int | bool | None]:
        """The metrics; all None for a follower whose camera never showed its
        reference ("acquired": false): it never moved, so its error says
        nothing. "acquired" is None when no camera frame was taken (an engine
        driven without observations, in tests)."""

        def rms(sq: float, n: int) -> float:
            return math.sqrt(sq / n) if n else math.nan

        straight = self.samples - self.turn_samples
        seen = {"frames": self.frames, "seen_ticks": self.seen_ticks}
        if self.frames and not self.seen_ticks:
            return {"acquired": False, **seen, "samples": self.samples, **dict.fromkeys(METRICS)}
        acquired = bool(self.seen_ticks) if self.frames else None
        if not self.samples:  # no tick measured (a run that ended before its first): nothing to say, not 0 m
            return {"acquired": acquired, **seen, "samples": 0, **dict.fromkeys(METRICS)}
        return {
            "acquired": acquired,
            **seen,
            "rms_m": self.rms_m(),
            "max_m": self.max_m,
            "samples": self.samples,
            "turn_rms_m": rms(self.turn_sum_sq_m2, self.turn_samples),
            "straight_rms_m": rms(self.sum_sq_m2 - self.turn_sum_sq_m2, straight),
            "turn_max_m": self.turn_max_m if self.turn_samples else None,  # no turn: no largest error in one
            "turn_samples": self.turn_samples,
            "turn_mean_lag_m": self.turn_along_sum_m / self.turn_samples if self.turn_samples else math.nan,
            "max_lag_m": self.max_lag_m,
            "max_ahead_m": self.max_ahead_m,
        }


@dataclass
class RunMetrics:
    """Every figure of the run that comes from the robots' states, one
    snapshot per tick (:meth:`record`)."""

    setup: WorldSetup
    followers: dict[int, FollowerMetrics] = field(init=False)
    contacts: Contacts = field(init=False)
    # Per follower, [sum, largest, ticks] of its formation error in each window of ERROR_WINDOW_S (m).
    windows: dict[int, list[list[float]]] = field(init=False)
    window_ticks: int = field(init=False)
    # A follower's error until its first stop (its agent killed or lost): time_s, rms_m, max_m.
    until_stopped: dict[int, dict[str, float]] = field(init=False, default_factory=dict)
    # Formation errors after a robot's return (world.recovery), fed by record().
    recoveries: list[Recovery] = field(init=False, default_factory=list)
    recorded: int = field(init=False, default=0)  # ticks recorded
    leader: LeaderTrack = field(init=False)  # the leader's distance from its path
    # Many followers: their errors' sums, kept here (the followers' own written on reading).
    at_once: FormationErrors | None = field(init=False, default=None)
    _digest: hashlib._Hash = field(init=False)

    def __post_init__(self) -> None:
        sc = self.setup
        self.followers = {rid: FollowerMetrics() for rid in sc.follower_ids}
        self.contacts = Contacts(sc.diameter_m, sc.obstacles, sc.dt_s)
        self.windows = {rid: [] for rid in sc.follower_ids}
        self.window_ticks = max(1, round(ERROR_WINDOW_S / sc.dt_s))
        self.leader = LeaderTrack(sc.leader.waypoints)
        self._digest = hashlib.sha256()
        if len(self.followers) >= ERRORS_AT_ONCE_FROM:
            self.at_once = FormationErrors(sc, self.window_ticks, TURN_RATE_RPS)

    def record(self, snap: Snapshot, tick: int) -> None:
        """The figures of tick ``tick``, whose state ``snap`` is."""
        sc = self.setup
        poses = {rid: pose for rid, (pose, _, _) in snap.items()}
        if self.at_once is None:
            errors = self._errors(snap, poses)
        else:
            err = self.at_once.add(snap)
            errors = dict(zip(self.at_once.rids, err.tolist(), strict=True)) if self.recoveries else {}
        self.recorded += 1
        for rec in self.recoveries:
            rec.add(tick, errors)
        self.contacts.measure(poses, tick)
        lead = poses[sc.leader.robot_id]
        self.leader.add(lead.x_m, lead.y_m)
        h = self._digest
        if self.at_once is None:
            for rid in sorted(snap):
                h.update(struct.pack("<3d", *snap[rid][0]))
            return
        # Many robots: one update of every pose's bytes, the same digest as one update per robot.
        packed = self.at_once.pose_bytes()
        if packed is None:
            packed = struct.pack(f"<{3 * len(poses)}d", *itertools.chain.from_iterable(poses[r] for r in sorted(poses)))
        h.update(packed)

    def _errors(self, snap: Snapshot, poses: dict[int, Pose]) -> dict[int, float]:
        """Each follower's formation error in ``snap``, added to its metrics and windows, one by one."""
        sc = self.setup
        errors: dict[int, float] = {}
        for rid, metrics in self.followers.items():
            pose, _, formation = snap[rid]
            reference = sc.formation_by_code(formation).slots[rid].reference
            ref_pose, ref_command, _ = snap[reference]
            tx, ty = target_in(sc, rid, formation, poses)
            ex, ey = tx - pose.x_m, ty - pose.y_m
            along = ex * math.cos(ref_pose.theta_rad) + ey * math.sin(ref_pose.theta_rad)
            turning = abs(ref_command[1] - ref_command[0]) / sc.width_m >= TURN_RATE_RPS
            err = math.hypot(ex, ey)
            errors[rid] = err
            metrics.add(err, along, turning)
            windows = self.windows[rid]
            if self.recorded % self.window_ticks == 0:
                windows.append([0.0, 0.0, 0])
            w = windows[-1]
            w[0], w[1], w[2] = w[0] + err, max(w[1], err), w[2] + 1
        return errors

    def _written(self) -> None:
        """The followers' metrics brought up to date from the sums kept at once, if so kept."""
        if self.at_once is not None:
            self.at_once.write(self.followers)

    def stopped(self, rid: int, time_s: float) -> None:
        """Follower ``rid`` stops (its process gone) at ``time_s``: its error so far is kept, once."""
        if rid in self.followers and rid not in self.until_stopped:
            self._written()
            m = self.followers[rid]
            self.until_stopped[rid] = {"time_s": time_s, "rms_m": m.rms_m(), "max_m": m.max_m}

    def digest(self) -> str:
        return self._digest.hexdigest()

    def error_windows(self) -> dict[str, object]:
        """Per follower, the mean and the largest formation error of each window
        (the last one may be shorter), in m."""
        window_s = self.window_ticks * self.setup.dt_s
        if self.at_once is not None:
            mean_m, max_m = self.at_once.error_windows()
            return {"window_s": window_s, "mean_m": mean_m, "max_m": max_m}
        windows = self.windows.items()
        return {
            "window_s": window_s,
            "mean_m": {str(r): [round(w[0] / w[2], 4) for w in ws] for r, ws in windows},
            "max_m": {str(r): [round(w[1], 4) for w in ws] for r, ws in windows},
        }

    def follower_summary(self, rid: int) -> dict[str, object]:
        self._written()
        out: dict[str, object] = dict(self.followers[rid].as_dict())
        if rid in self.until_stopped:
            out["until_stopped"] = self.until_stopped[rid]
        return out


# The 99% point of chi-square with 2 degrees of freedom (-2 ln 0.01): a consistent
# filter's NEES of a 2-D estimate lies beyond it on 1% of the ticks.
NEES_TICK_BOUND_99 = 9.2103


@dataclass
class TargetErrors:
    """One follower's target estimate against the truth, batch by batch: the
    raw reading's error (ticks with a reading), the EKF's (every tick with an
    estimate, and only the ticks with a reading too, where the two compare
    tick for tick), and the EKF's normalised estimation error squared (NEES,
    e' P^-1 e over the ticks with a covariance; 2 on average for a
    consistent filter of a 2-D estimate). Arrays are world frame except the
    covariance, the follower's own (xx, xy, yy) of (x right, y ahead)."""

    sums: dict[str, float] = field(default_factory=dict)

    def _add(self, name: str, values: np.ndarray) -> None:
        self.sums[name + "_sum"] = self.sums.get(name + "_sum", 0.0) + float(np.sum(values))
        self.sums[name + "_n"] = self.sums.get(name + "_n", 0.0) + int(values.size)

    def add(
        self, pose: np.ndarray, target: np.ndarray, measured: np.ndarray, estimate: np.ndarray, cov: np.ndarray
    ) -> None:
        """n ticks: the follower's pose (n x 3), its true target, the raw
        reading's and the EKF's targets (n x 2, NaN when none) and the EKF's
        covariance (n x 3, NaN when none)."""
        has_target = ~np.isnan(target[:, 0])
        seen = has_target & ~np.isnan(measured[:, 0])
        est = has_target & ~np.isnan(estimate[:, 0])
        sq_meas = np.sum((measured[seen] - target[seen]) ** 2, axis=1)
        sq_est = np.sum((estimate - target) ** 2, axis=1)
        self._add("measured_sq", sq_meas)
        self._add("ekf_sq", sq_est[est])
        self._add("ekf_seen_sq", sq_est[est & seen])
        ok = est & ~np.isnan(cov[:, 0])
        nees = nees_body(pose[ok, 2], (estimate - target)[ok], cov[ok])
        nees = nees[np.isfinite(nees)]
        self._add("nees", nees)
        self._add("nees_beyond", (nees > NEES_TICK_BOUND_99).astype(float))

    def _mean(self, name: str) -> float | None:
        n = self.sums.get(name + "_n", 0.0)
        return self.sums[name + "_sum"] / n if n else None

    def stats(self) -> dict[str, float | int | None]:
        """RMS errors in m, the mean NEES, its ticks and the share of them beyond NEES_TICK_BOUND_99."""

        def rms(name: str) -> float | None:
            mean = self._mean(name)
            return None if mean is None else math.sqrt(mean)

        return {
            "measured_rms_m": rms("measured_sq"),
            "ekf_rms_m": rms("ekf_sq"),
            "ekf_rms_seen_m": rms("ekf_seen_sq"),
            "nees_mean": self._mean("nees"),
            "nees_ticks": int(self.sums.get("nees_n", 0)),
            "nees_beyond_99": self._mean("nees_beyond"),
        }


def nees_body(theta_rad: np.ndarray, err_world: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """NEES e' P^-1 e of world-frame errors (n x 2) against covariances in the
    follower's frame (x right, y ahead; n x 3 of xx, xy, yy), the follower
    heading ``theta_rad``. NaN where P is not positive definite."""
    s, c = np.sin(theta_rad), np.cos(theta_rad)
    bx = err_world[:, 0] * s - err_world[:, 1] * c  # x right is (sin, -cos) in the world
    by = err_world[:, 0] * c + err_world[:, 1] * s
    xx, xy, yy = cov[:, 0], cov[:, 1], cov[:, 2]
    det = xx * yy - xy * xy
    with np.errstate(divide="ignore", invalid="ignore"):
        out = (yy * bx * bx - 2.0 * xy * bx * by + xx * by * by) / det
    return np.where((det > 0) & (xx > 0), out, np.nan)
