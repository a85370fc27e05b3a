"""The world's state and physics, with no I/O: one object the world's tick
(world.tick) drives tick by tick (and tests drive directly).

It integrates every robot (eq. 7-10), simulates the cameras and the leader's
obstacle sensing, holds each robot's latest command and stops a robot whose
command is stale or whose process is gone, and applies the scenario's sensor
and actuator faults and wheel noise (``hardware_faults``). The run's figures
are world.metrics' (formation errors, recoveries, digest) and
world.contacts'. A command reaches :meth:`WorldEngine.set_command` judged
already (world.commands): the engine executes it as given.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from formation_swarm.world.camera import CameraFrame, MarkerReading, Seen, pose_array
from formation_swarm.world.contacts import CONTACTS_LISTED
from formation_swarm.world.hardware_faults import SENSOR_EFFECT, CameraFaults, Wheels, counts_table
from formation_swarm.world.kinematics import Pose, _step_unchecked, from_body_frame, to_body_frame
from formation_swarm.world.metrics import (
    ERROR_WINDOW_S,
    METRICS,
    TURN_RATE_RPS,
    FollowerMetrics,
    RunMetrics,
    Snapshot,
    target_in,
)
from formation_swarm.world.recovery import Recovery
from formation_swarm.world.setup import WorldSetup

# Importable from here, where they were defined before the metrics had a module of their own.
__all__ = [
    "CONTACTS_LISTED",
    "ERROR_WINDOW_S",
    "METRICS",
    "TURN_RATE_RPS",
    "FollowerMetrics",
    "RobotState",
    "WorldEngine",
    "start_poses",
]

# Up to this many followers their true targets are taken one by one: numpy's fixed
# cost per call is dearer than the arithmetic of a few.
TARGETS_ONE_BY_ONE = 24

Observed = tuple[tuple[float, float, float], list, list]  # own pose, marker readings, obstacles in range


@dataclass
class RobotState:
    pose: Pose
    rng: np.random.Generator
    command: tuple[float, float] = (0.0, 0.0)
    command_time_s: float = -math.inf
    formation: int = 0
    alive: bool = True
    answered: bool = False


def start_poses(sc: WorldSetup) -> dict[int, Pose]:
    """Every robot on its slot of the leader's first formation at the path's
    start, all heading along the path's first leg."""
    wp = sc.leader.waypoints
    heading = math.atan2(wp[1][1] - wp[0][1], wp[1][0] - wp[0][0])
    start = Pose(wp[0][0], wp[0][1], heading)
    form = sc.formation_by_code(sc.code_of(sc.leader.formation))
    return {rid: Pose(*from_body_frame(start, pt.x_m, pt.y_m), heading) for rid, pt in form.slot_positions().items()}


@dataclass
class WorldEngine:
    scenario: WorldSetup
    seed: int
    tick: int = 0
    robots: dict[int, RobotState] = field(init=False)
    metrics: RunMetrics = field(init=False)
    stale_stops: int = field(init=False, default=0)
    formation_events: list[dict[str, object]] = field(init=False, default_factory=list)
    cameras: dict[int, CameraFaults] = field(init=False, default_factory=dict)  # followers only
    wheels: dict[int, Wheels] = field(init=False, default_factory=dict)
    # The state of the last tick stepped from, until record() takes its metrics.
    _pending: Snapshot | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        sc = self.scenario
        code = sc.code_of(sc.leader.formation)
        self.robots = {
            rid: RobotState(pose, np.random.default_rng([self.seed, rid]), formation=code)
            for rid, pose in start_poses(sc).items()
        }
        self.metrics = RunMetrics(sc)
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

    @property
    def time_s(self) -> float:
        return self.tick * self.scenario.dt_s

    @property
    def alive_ids(self) -> list[int]:
        return [rid for rid, r in self.robots.items() if r.alive]

    @property
    def recoveries(self) -> list[Recovery]:
        """The Recovery records the metrics feed (world.process_faults adds to them)."""
        return self.metrics.recoveries

    def observation(self, rid: int) -> Observed:
        """(own pose, marker readings, obstacles in range) for robot ``rid`` now."""
        return self.observations([rid])[rid]

    def observations(self, rids: list[int]) -> dict[int, Observed]:
        """:meth:`observation` of each robot of ``rids``, every camera of the tick
        taken at once (world.camera.CameraFrame: the same readings, the same draws)."""
        return dict(self.each_observation(rids))

    def each_observation(self, rids: list[int]) -> Iterator[tuple[int, Observed]]:
        """(rid, :meth:`observation`) of each robot of ``rids`` in turn. Every
        camera of the tick is read at once (world.camera.CameraFrame), and every
        robot's noise comes from its own generator: the order of ``rids``
        changes no reading."""
        frame = self._frame()
        leader = self.scenario.leader.robot_id
        followers = [(rid, self.robots[rid].rng) for rid in rids if rid != leader]
        seen_by = frame.observe_many(followers) if followers else {}
        for rid in rids:
            yield rid, self._observed(rid, frame, seen_by.get(rid, []))

    def observation_batch(self, rids: list[int]) -> tuple[list[int], Seen, dict[int, Observed]]:
        """:meth:`observations` of ``rids``, those of the followers whose camera
        no fault is scheduled on as arrays: (those followers in the order of
        ``rids``, their readings one after the other, every other robot's
        observation: the leader's, a faulty camera's). The same readings, the
        same draws, the same counts."""
        frame = self._frame()
        leader = self.scenario.leader.robot_id
        plain = [rid for rid in rids if rid == leader or self.cameras[rid].effects]
        fast = [rid for rid in rids if rid != leader and not self.cameras[rid].effects]
        seen = frame.observe_arrays([(rid, self.robots[rid].rng) for rid in fast])
        # Whether each camera showed its reference: a reading of the reference's id.
        refs = np.array([self._reference(rid) for rid in fast], dtype=np.int64)
        camera = np.repeat(np.arange(len(fast)), seen.counts)
        showed = np.bincount(camera[seen.ids == refs[camera]], minlength=len(fast)).tolist()
        for rid, hit in zip(fast, showed, strict=True):
            metrics = self.metrics.followers[rid]
            metrics.frames += 1
            metrics.seen_ticks += hit > 0
        seen_by = frame.observe_many([(rid, self.robots[rid].rng) for rid in plain if rid != leader])
        return fast, seen, {rid: self._observed(rid, frame, seen_by.get(rid, [])) for rid in plain}

    def _frame(self) -> CameraFrame:
        return CameraFrame({i: s.pose for i, s in self.robots.items()}, self.scenario.camera)

    def _reference(self, rid: int) -> int:
        """The robot follower ``rid`` follows in the formation it flies."""
        return self.scenario.formation_by_code(self.robots[rid].formation).slots[rid].reference

    def _observed(self, rid: int, frame: CameraFrame, readings: list) -> Observed:
        """Robot ``rid``'s observation: a follower's ``readings`` once its camera's
        faults act, counted in its metrics; the leader's obstacles in range."""
        sc = self.scenario
        r = self.robots[rid]
        obstacles = []
        if rid != sc.leader.robot_id:
            camera = self.cameras[rid]
            if camera.effects:  # faults scheduled on this camera (active or not: it decides)
                seen = camera.apply(self.tick, frame.poses, [MarkerReading(*m) for m in readings])
                readings = [tuple(m) for m in seen]
            reference = self._reference(rid)
            metrics = self.metrics.followers[rid]
            metrics.frames += 1
            metrics.seen_ticks += any(m[0] == reference for m in readings)
        else:
            # The leader uses no camera: it flies its path and senses obstacles.
            for ob in sc.obstacles:
                xb, yb = to_body_frame(r.pose, ob.x_m, ob.y_m)
                dist = math.hypot(xb, yb)
                if dist - ob.radius_m <= sc.leader.sensing_range_m:
                    obstacles.append((dist, math.atan2(xb, yb), ob.radius_m))
        return tuple(r.pose), readings, obstacles

    def set_command(self, rid: int, left_mps: float, right_mps: float, formation: int, now_s: float) -> None:
        """Robot ``rid`` runs these wheel speeds from now (``now_s``, on the clock
        staleness is measured on) and flies ``formation``. Taken as given: the
        speeds within the motors' limit and the code one of the run's
        (world.commands judged the command)."""
        r = self.robots[rid]
        r.command = (left_mps, right_mps)
        r.command_time_s = now_s
        if formation != r.formation:
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
        if rid in self.metrics.followers and rid not in self.metrics.until_stopped:
            self.record()  # the ticks before this one (recording sooner changes nothing but when)
            self.metrics.stopped(rid, self.time_s)

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
        return target_in(self.scenario, rid, formation, poses)

    def targets_in(self, formations: Mapping[int, int], poses: Mapping[int, Pose]) -> list[tuple[int, float, float]]:
        """(rid, x, y): :meth:`target_in` of each follower of ``formations``
        (follower: formation code), the arithmetic done for all at once: math's
        cosines and sines, then the same operations in the same order
        (from_body_frame's), so the same numbers."""
        rids = list(formations)
        if len(rids) <= TARGETS_ONE_BY_ONE:
            return [(rid, *self.target_in(rid, code, poses)) for rid, code in formations.items()]
        codes = np.fromiter(formations.values(), dtype=np.int64, count=len(rids))
        refs, ox, oy = np.zeros(len(rids), np.int64), np.zeros(len(rids)), np.zeros(len(rids))
        for code in sorted(set(formations.values())):
            at = np.flatnonzero(codes == code)
            slots = self.scenario.formation_by_code(code).slots
            refs[at] = [slots[rids[k]].reference for k in at.tolist()]
            ox[at] = [slots[rids[k]].offset[0] for k in at.tolist()]
            oy[at] = [slots[rids[k]].offset[1] for k in at.tolist()]
        ref = pose_array(poses, refs.tolist())
        heading = ref[:, 2].tolist()
        c, s = np.array(list(map(math.cos, heading))), np.array(list(map(math.sin, heading)))
        x = ref[:, 0] + ox * s + oy * c
        y = ref[:, 1] - ox * c + oy * s
        return list(zip(rids, x.tolist(), y.tolist(), strict=True))

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
            r.pose = _step_unchecked(x, y, th, vl, vr, width=width, dt=dt)
        self.tick += 1

    def record(self) -> None:
        """The metrics of the last tick stepped from, if not yet recorded."""
        snap, self._pending = self._pending, None
        if snap is not None:
            self.metrics.record(snap, self.tick - 1)  # the snapshot is of the tick before the last step

    def digest(self) -> str:
        self.record()
        return self.metrics.digest()

    def summary(self) -> dict[str, object]:
        self.record()
        m, contacts = self.metrics, self.metrics.contacts
        return {
            "ticks": self.tick,
            "sim_time_s": self.time_s,
            "followers": {str(rid): m.follower_summary(rid) for rid in m.followers},
            "min_distance_m": contacts.min_distance_m,
            "robot_diameter_m": self.scenario.diameter_m,
            "collisions": contacts.collisions,
            "obstacle_collisions": contacts.obstacle_collisions,
            "contacts": contacts.listed,  # the first CONTACTS_LISTED; obstacles by their index in the scenario
            "stale_stops": self.stale_stops,
            # By tick, then robot: commands of one tick arrive in any order.
            "formation_events": sorted(self.formation_events, key=lambda e: (e["tick"], e["robot"])),
            "error_windows": m.error_windows(),
            # {fault: {robot: {"ticks": active ticks, effect: count}}} (docs/faults.md)
            "sensor_faults": counts_table({rid: c.effects for rid, c in self.cameras.items()}, SENSOR_EFFECT),
            "actuator_faults": counts_table({rid: w.effects for rid, w in self.wheels.items()}, "moving_ticks"),
            "trajectory_digest": self.digest(),
            "final_poses": {str(rid): list(r.pose) for rid, r in self.robots.items()},
            # The leader's largest distance from its waypoints' polyline, and from the last one at the end.
            "leader_path": m.leader.as_dict(self.robots[self.scenario.leader.robot_id].pose),
            "dead_robots": [rid for rid, r in self.robots.items() if not r.alive],
        }
