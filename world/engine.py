"""The world's state and physics, with no I/O: one object the world process
drives tick by tick (and tests drive directly).

It integrates every robot (eq. 7-10), simulates the cameras and the leader's
obstacle sensing, holds each robot's latest command and stops a robot whose
command is stale or whose process is gone, applies the scenario's sensor and
actuator faults and wheel noise (``hardware_faults``), and keeps the run's
metrics: formation error per follower, minimum distance, collisions, what
each fault did, a digest of the trajectories.
"""

from __future__ import annotations

import hashlib
import math
import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from formation_swarm.world.camera import CameraFrame
from formation_swarm.world.hardware_faults import SENSOR_EFFECT, CameraFaults, Wheels, counts_table
from formation_swarm.world.kinematics import Pose, _step_unchecked, from_body_frame, to_body_frame
from formation_swarm.world.recovery import Recovery

if TYPE_CHECKING:  # an annotation only: the world's physics does not import the application layer
    from formation_swarm.spec.scenario import Scenario

# A reference turning at least this fast (from its wheel commands) is "in a turn"
# for the metrics; the paper's path turns at 0.25 rad/s, pure pursuit on a
# straight line stays well under this.
TURN_RATE_RPS = 0.1
# The formation error over time, for recoveries: each follower's mean and
# largest error in every window of this many seconds (rounded to whole ticks).
# A second smooths the camera noise that a follower of a follower amplifies
# (fig11's robot 3: 10-35% of its ticks above 0.5 m in steady flight).
ERROR_WINDOW_S = 1.0
# Contacts listed in the summary with their tick and who touched whom (all are
# counted): enough to find the first ones; a 200-robot swarm that folds has hundreds.
CONTACTS_LISTED = 50


@dataclass
class RobotState:
    pose: Pose
    rng: np.random.Generator
    command: tuple[float, float] = (0.0, 0.0)
    command_time_s: float = -math.inf
    formation: int = 0
    alive: bool = True
    answered: bool = False


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
    frames: int = 0  # camera frames taken for it (observation())
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
        if not self.samples:  # no tick measured (a run that ended before its first): nothing to say, not 0 m
            return {
                "acquired": bool(self.seen_ticks) if self.frames else None,
                **seen,
                "samples": 0,
                **dict.fromkeys(METRICS),
            }
        return {
            "acquired": bool(self.seen_ticks) if self.frames else None,
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


def start_poses(sc: Scenario) -> dict[int, Pose]:
    """Every robot on its slot of the leader's first formation at the path's
    start, all heading along the path's first leg."""
    wp = sc.leader.waypoints
    heading = math.atan2(wp[1][1] - wp[0][1], wp[1][0] - wp[0][0])
    start = Pose(wp[0][0], wp[0][1], heading)
    form = sc.formations[sc.leader.formation]
    return {rid: Pose(*from_body_frame(start, pt.x_m, pt.y_m), heading) for rid, pt in form.slot_positions().items()}


@dataclass
class WorldEngine:
    scenario: Scenario
    seed: int
    tick: int = 0
    robots: dict[int, RobotState] = field(init=False)
    metrics: dict[int, FollowerMetrics] = field(init=False)
    min_distance_m: float = field(init=False, default=math.inf)
    collisions: int = field(init=False, default=0)
    obstacle_collisions: int = field(init=False, default=0)
    stale_stops: int = field(init=False, default=0)
    clamped_commands: int = field(init=False, default=0)  # wheel speeds beyond robot.max_wheel_mps
    formation_events: list[dict[str, object]] = field(init=False, default_factory=list)
    # Per follower, [sum, largest, ticks] of its formation error in each window of ERROR_WINDOW_S (m).
    error_windows: dict[int, list[list[float]]] = field(init=False, default_factory=dict)
    _window_ticks: int = field(init=False, default=1)
    # A follower's error until its first stop (its agent killed or lost): time_s, rms_m, max_m.
    until_stopped: dict[int, dict[str, float]] = field(init=False, default_factory=dict)
    _recorded: int = field(init=False, default=0)  # ticks whose metrics were taken
    cameras: dict[int, CameraFaults] = field(init=False, default_factory=dict)  # followers only
    wheels: dict[int, Wheels] = field(init=False, default_factory=dict)
    # Formation errors after a robot's return (world.recovery), fed by record().
    recoveries: list[Recovery] = field(init=False, default_factory=list)
    _touching: set[tuple[int, int]] = field(init=False, default_factory=set)
    # The first CONTACTS_LISTED contacts counted: when, and who touched whom or what.
    contacts: list[dict[str, object]] = field(init=False, default_factory=list)
    _pair_index: tuple[np.ndarray, np.ndarray] = field(init=False, default=(np.zeros(0, int), np.zeros(0, int)))
    _digest: hashlib._Hash = field(init=False)
    # The state of the last tick stepped from, until record() takes its metrics.
    _pending: dict[int, tuple[Pose, tuple[float, float], int]] | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        sc = self.scenario
        code = sc.code_of(sc.leader.formation)
        self.robots = {
            rid: RobotState(pose, np.random.default_rng([self.seed, rid]), formation=code)
            for rid, pose in start_poses(sc).items()
        }
        self.metrics = {rid: FollowerMetrics() for rid in sc.follower_ids}
        self.error_windows = {rid: [] for rid in sc.follower_ids}
        self._window_ticks = max(1, round(ERROR_WINDOW_S / sc.dt_s))
        for rid in sc.robots:
            # The leader has no camera in this model: camera faults are the followers'.
            if rid != sc.leader.robot_id:
                self.cameras[rid] = CameraFaults(
                    sc.faults, seed=self.seed, robot_id=rid, dt_s=sc.dt_s, camera=sc.camera
                )
            self.wheels[rid] = Wheels(
                sc.faults,
                seed=self.seed,
                robot_id=rid,
                dt_s=sc.dt_s,
                noise_sigma_mps=sc.wheel_noise_mps,
                max_wheel_mps=sc.max_wheel_mps,
            )
        self._digest = hashlib.sha256()

    @property
    def time_s(self) -> float:
        return self.tick * self.scenario.dt_s

    @property
    def alive_ids(self) -> list[int]:
        return [rid for rid, r in self.robots.items() if r.alive]

    def observation(self, rid: int) -> tuple[tuple[float, float, float], list, list]:
        """(own pose, marker readings, obstacles in range) for robot ``rid`` now."""
        return self.observations([rid])[rid]

    def observations(self, rids: list[int]) -> dict[int, tuple[tuple[float, float, float], list, list]]:
        """:meth:`observation` of each robot of ``rids``, every camera of the tick
        taken at once (world.camera.CameraFrame: the same readings, the same draws)."""
        return dict(self.each_observation(rids))

    def each_observation(self, rids: list[int]) -> Iterator[tuple[int, tuple[tuple[float, float, float], list, list]]]:
        """(rid, :meth:`observation`) of each robot of ``rids`` in turn, so that
        one can be sent before the next is taken. Every robot's comes from its
        own generator: the order of ``rids`` changes no reading."""
        sc = self.scenario
        leader = sc.leader.robot_id
        frame = None
        poses: dict[int, Pose] = {}
        for rid in rids:
            r = self.robots[rid]
            readings: list = []
            obstacles = []
            if rid != leader:
                # The leader uses no camera: it flies its path and senses obstacles.
                if frame is None:
                    poses = {i: s.pose for i, s in self.robots.items()}
                    frame = CameraFrame(poses, sc.camera)
                seen = self.cameras[rid].apply(self.tick, poses, frame.observe(rid, r.rng))
                readings = [tuple(m) for m in seen]
                reference = sc.formation_by_code(r.formation).slots[rid].reference
                metrics = self.metrics[rid]
                metrics.frames += 1
                metrics.seen_ticks += any(m[0] == reference for m in seen)
            else:
                for ob in sc.obstacles:
                    xb, yb = to_body_frame(r.pose, ob.x_m, ob.y_m)
                    dist = math.hypot(xb, yb)
                    if dist - ob.radius_m <= sc.leader.sensing_range_m:
                        obstacles.append((dist, math.atan2(xb, yb), ob.radius_m))
            yield rid, (tuple(r.pose), readings, obstacles)

    def set_command(self, rid: int, left_mps: float, right_mps: float, formation: int, now_s: float) -> None:
        r = self.robots[rid]
        limit = self.scenario.max_wheel_mps
        if not (-limit <= left_mps <= limit and -limit <= right_mps <= limit):
            self.clamped_commands += 1  # the robot's motors cannot do more, whatever it is told
            left_mps = min(max(left_mps, -limit), limit)
            right_mps = min(max(right_mps, -limit), limit)
        r.command = (left_mps, right_mps)
        r.command_time_s = now_s
        if formation != r.formation and formation < len(self.scenario.formation_names):
            self.formation_events.append(
                {
                    "tick": self.tick,
                    "time_s": self.time_s,
                    "robot": rid,
                    "formation": self.scenario.formation_names[formation],
                }
            )
            r.formation = formation

    def kill(self, rid: int) -> None:
        """The robot's process is gone: it stops where it is, until revived.
        A follower's error up to its first stop is kept (``until_stopped``):
        its whole run's figures include the robot standing after it."""
        r = self.robots[rid]
        r.alive = False
        r.command = (0.0, 0.0)
        if rid in self.metrics and rid not in self.until_stopped:
            self.record()  # the ticks before this one (recording sooner changes nothing but when)
            m = self.metrics[rid]
            self.until_stopped[rid] = {"time_s": self.time_s, "rms_m": m.rms_m(), "max_m": m.max_m}

    def revive(self, rid: int) -> None:
        """The robot's agent is back (a fresh process, a session regained): it
        gets observations again and holds still until its first command."""
        r = self.robots[rid]
        r.alive, r.answered = True, False
        r.command, r.command_time_s = (0.0, 0.0), -math.inf

    def true_target(self, rid: int) -> tuple[float, float]:
        """Follower ``rid``'s true virtual target now (eq. 2 on true poses), in the
        formation it flies: the code of its last command, so at a formation
        switch tick the new formation's slot."""
        return self.target_in(rid, self.robots[rid].formation, {i: r.pose for i, r in self.robots.items()})

    def target_in(self, rid: int, formation: int, poses: Mapping[int, Pose]) -> tuple[float, float]:
        """Follower ``rid``'s true virtual target in ``formation`` among ``poses`` (eq. 2)."""
        slot = self.scenario.formation_by_code(formation).slots[rid]
        return from_body_frame(poses[slot.reference], slot.offset[0], slot.offset[1])

    def step(self, now_s: float) -> None:
        """Integrate tick k to tick k+1.

        ``now_s`` is the clock staleness is measured on (sim time in
        lockstep, wall time in real time). The metrics of tick k (formation
        errors, contacts, the trajectory digest) come from a snapshot of its
        state taken here and are computed by :meth:`record`: the world calls
        it once tick k+1 is published, while the agents work, and ``step``
        and ``summary`` call it too, so no tick is skipped and the figures do
        not depend on when it runs.
        """
        self.record()
        self._pending = {rid: (r.pose, r.command, r.formation) for rid, r in self.robots.items()}
        sc = self.scenario
        width, dt = sc.width_m, sc.dt_s
        for rid, r in self.robots.items():
            vl, vr = r.command
            if not r.alive:
                vl = vr = 0.0
            elif now_s - r.command_time_s > sc.stale_after_s + 1e-9:
                if r.command != (0.0, 0.0) and r.command_time_s > -math.inf:
                    self.stale_stops += 1
                r.command = (0.0, 0.0)
                vl = vr = 0.0
            vl, vr = self.wheels[rid].turn(self.tick, vl, vr)
            x, y, th = r.pose
            r.pose = _step_unchecked(x, y, th, vl, vr, width, dt)
        self.tick += 1

    def record(self) -> None:
        """The metrics of the last tick stepped from, if not yet recorded."""
        snap, self._pending = self._pending, None
        if snap is None:
            return
        sc = self.scenario
        errors: dict[int, float] = {}
        poses = {rid: pose for rid, (pose, _, _) in snap.items()}
        for rid, metrics in self.metrics.items():
            pose, _, formation = snap[rid]
            reference = sc.formation_by_code(formation).slots[rid].reference
            ref_pose, ref_command, _ = snap[reference]
            tx, ty = self.target_in(rid, formation, poses)
            ex, ey = tx - pose.x_m, ty - pose.y_m
            along = ex * math.cos(ref_pose.theta_rad) + ey * math.sin(ref_pose.theta_rad)
            turning = abs(ref_command[1] - ref_command[0]) / sc.width_m >= TURN_RATE_RPS
            err = math.hypot(ex, ey)
            errors[rid] = err
            metrics.add(err, along, turning)
            windows = self.error_windows[rid]
            if self._recorded % self._window_ticks == 0:
                windows.append([0.0, 0.0, 0])
            w = windows[-1]
            w[0], w[1], w[2] = w[0] + err, max(w[1], err), w[2] + 1
        self._recorded += 1
        for rec in self.recoveries:
            rec.add(self.tick - 1, errors)  # the snapshot is of the tick before the last step
        self._contacts(poses)
        h = self._digest
        for rid in sorted(snap):
            h.update(struct.pack("<3d", *snap[rid][0]))

    def _contacts(self, poses: dict[int, Pose]) -> None:
        """Collisions (robot pairs, robots and obstacles) and the minimum distance
        of one tick. numpy measures every pair at once; the pairs it finds near
        the minimum or near touching (within CameraFrame.SLACK) are measured
        again with math.hypot, which decides, as the pair loop did."""
        sc = self.scenario
        ids = sorted(poses)
        if len(ids) <= CameraFrame.SCALAR_MAX:
            self._contacts_by_pairs(ids, poses)
            return
        xy = np.array([(poses[i][0], poses[i][1]) for i in ids], dtype=float).reshape(-1, 2)
        slack = CameraFrame.SLACK
        touching: set[tuple[int, int]] = set()
        if len(ids) > 1:
            ia, ib = self._pairs(len(ids))
            d = np.hypot(xy[ia, 0] - xy[ib, 0], xy[ia, 1] - xy[ib, 1])
            near = (d <= d.min() * (1.0 + slack) + slack) | (d < sc.diameter_m * (1.0 + slack) + slack)
            for k in np.flatnonzero(near).tolist():
                a, b = ids[ia[k]], ids[ib[k]]
                pa, pb = poses[a], poses[b]
                dist = math.hypot(pa.x_m - pb.x_m, pa.y_m - pb.y_m)
                self.min_distance_m = min(self.min_distance_m, dist)
                if dist < sc.diameter_m:
                    touching.add((a, b))
        for k, ob in enumerate(sc.obstacles):
            reach = ob.radius_m + 0.5 * sc.diameter_m
            d = np.hypot(xy[:, 0] - ob.x_m, xy[:, 1] - ob.y_m)
            for i in np.flatnonzero(d < reach * (1.0 + slack) + slack).tolist():
                p = poses[ids[i]]
                if math.hypot(p.x_m - ob.x_m, p.y_m - ob.y_m) < reach:
                    touching.add((ids[i], -1 - k))
        self._touched(touching)

    def _contacts_by_pairs(self, ids: list[int], poses: dict[int, Pose]) -> None:
        """:meth:`_contacts` for a few robots: every pair measured with math.hypot,
        which decides all the same (numpy's fixed cost per call is dearer here
        than the pairs it would spare)."""
        sc = self.scenario
        touching: set[tuple[int, int]] = set()
        least = self.min_distance_m
        for n, a in enumerate(ids):
            xa, ya = poses[a][0], poses[a][1]
            for b in ids[n + 1 :]:
                dist = math.hypot(xa - poses[b][0], ya - poses[b][1])
                least = min(least, dist)
                if dist < sc.diameter_m:
                    touching.add((a, b))
            for k, ob in enumerate(sc.obstacles):
                if math.hypot(xa - ob.x_m, ya - ob.y_m) < ob.radius_m + 0.5 * sc.diameter_m:
                    touching.add((a, -1 - k))
        self.min_distance_m = least
        self._touched(touching)

    def _touched(self, touching: set[tuple[int, int]]) -> None:
        """The contacts of one tick (of the snapshot record() takes: the tick
        before the last step): those that are new are counted, and the first
        CONTACTS_LISTED listed."""
        new = touching - self._touching
        self.collisions += sum(1 for _, b in new if b > 0)
        self.obstacle_collisions += sum(1 for _, b in new if b < 0)
        self._touching = touching
        if new and len(self.contacts) < CONTACTS_LISTED:
            tick = self.tick - 1
            for a, b in sorted(new, key=lambda pair: (pair[0], -pair[1] if pair[1] < 0 else pair[1])):
                what: dict[str, object] = {"robots": [a, b]} if b > 0 else {"robot": a, "obstacle": -1 - b}
                self.contacts.append({"tick": tick, "time_s": round(tick * self.scenario.dt_s, 6), **what})
            del self.contacts[CONTACTS_LISTED:]

    def _pairs(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Row and column of every pair i < j of ``n`` robots (cached: n rarely changes)."""
        if self._pair_index[0].size != n * (n - 1) // 2:
            self._pair_index = np.triu_indices(n, 1)
        return self._pair_index

    def digest(self) -> str:
        self.record()
        return self._digest.hexdigest()

    def _error_windows(self) -> dict[str, object]:
        """Per follower, the mean and the largest formation error of each window
        (the last one may be shorter), in m."""
        windows = self.error_windows.items()
        return {
            "window_s": self._window_ticks * self.scenario.dt_s,
            "mean_m": {str(r): [round(w[0] / w[2], 4) for w in ws] for r, ws in windows},
            "max_m": {str(r): [round(w[1], 4) for w in ws] for r, ws in windows},
        }

    def _follower_summary(self, rid: int) -> dict[str, object]:
        out: dict[str, object] = dict(self.metrics[rid].as_dict())
        if rid in self.until_stopped:
            out["until_stopped"] = self.until_stopped[rid]
        return out

    def summary(self) -> dict[str, object]:
        self.record()
        return {
            "ticks": self.tick,
            "sim_time_s": self.time_s,
            "followers": {str(rid): self._follower_summary(rid) for rid in self.metrics},
            "min_distance_m": self.min_distance_m,
            "robot_diameter_m": self.scenario.diameter_m,
            "collisions": self.collisions,
            "obstacle_collisions": self.obstacle_collisions,
            "contacts": self.contacts,  # the first CONTACTS_LISTED; obstacles by their index in the scenario
            "stale_stops": self.stale_stops,
            "clamped_commands": self.clamped_commands,
            # By tick, then robot: commands of one tick arrive in any order.
            "formation_events": sorted(self.formation_events, key=lambda e: (e["tick"], e["robot"])),
            "error_windows": self._error_windows(),
            # {fault: {robot: {"ticks": active ticks, effect: count}}} (docs/faults.md)
            "sensor_faults": counts_table({rid: c.effects for rid, c in self.cameras.items()}, SENSOR_EFFECT),
            "actuator_faults": counts_table({rid: w.effects for rid, w in self.wheels.items()}, "moving_ticks"),
            "trajectory_digest": self.digest(),
            "final_poses": {str(rid): list(r.pose) for rid, r in self.robots.items()},
            "dead_robots": [rid for rid, r in self.robots.items() if not r.alive],
        }
