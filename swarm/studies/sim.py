"""The bare closed loop: a leader on its path, followers on their law
(``controller.law``: the paper's controller unless the params name
another), the camera model and the kinematics, in one Python loop, with
every tick's true, measured and estimated target kept as arrays.

No world, roles or links: no obstacles, faults or formation changes. The
agents' unit tests use it (the EKF, l-psi, the closed loop). A run as
``swarm run`` flies it, in one process and with its digest, is the
engine's (formation_swarm.engine, ``swarm sim``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from formation_swarm.agents.controller import ControllerSetup, FollowerInput, MarkerReading
from formation_swarm.agents.follower import FollowerParams, make_controller
from formation_swarm.agents.formation import Formation, Slot
from formation_swarm.agents.geometry import Point
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.world import kinematics
from formation_swarm.world.camera import CameraParams, observe
from formation_swarm.world.kinematics import Pose, from_body_frame


@dataclass(frozen=True)
class ClosedLoopSetup:
    formation: Formation
    waypoints: Sequence[Sequence[float]]
    leader_speed_mps: float = 1.5
    leader_turn_rate_rps: float = 0.25
    duration_s: float = 40.0
    seed: int = 0
    camera: CameraParams = field(default_factory=CameraParams)
    follower: FollowerParams = field(default_factory=FollowerParams)
    # Per-follower overrides (e.g. static vs dynamic V_N side by side).
    follower_overrides: Mapping[int, FollowerParams] = field(default_factory=dict)
    max_wheel_mps: float = 3.0  # robot.max_wheel_mps's default


@dataclass
class ClosedLoopResult:
    times_s: np.ndarray
    poses: dict[int, np.ndarray]  # (T, 3) per robot
    true_targets: dict[int, np.ndarray]  # (T, 2) world frame
    measured_targets: dict[int, np.ndarray]  # (T, 2) world frame, NaN when unseen
    estimated_targets: dict[int, np.ndarray]  # (T, 2) world frame, NaN before the EKF starts
    vn: dict[int, np.ndarray]
    formation_error_m: dict[int, np.ndarray]  # follower to its true target

    def rms(self, rid: int, after_s: float = 0.0) -> float:
        e = self.formation_error_m[rid][self.times_s >= after_s]
        return float(np.sqrt(np.mean(e**2)))

    def max(self, rid: int, after_s: float = 0.0) -> float:
        return float(np.max(self.formation_error_m[rid][self.times_s >= after_s]))


def true_target(poses: Mapping[int, Pose], formation: Formation, rid: int) -> tuple[float, float]:
    """World position of ``rid``'s virtual target (eq. 2 on true poses)."""
    slot = formation.slots[rid]
    return from_body_frame(poses[slot.reference], slot.offset[0], slot.offset[1])


def initial_poses(formation: Formation, leader_pose: Pose) -> dict[int, Pose]:
    """Every robot on its slot, all with the leader's heading."""
    out = {}
    for rid, pt in formation.slot_positions().items():
        x, y = from_body_frame(leader_pose, pt.x_m, pt.y_m)
        out[rid] = Pose(x, y, leader_pose[2])
    return out


def run(setup: ClosedLoopSetup) -> ClosedLoopResult:
    form = setup.formation
    fp = setup.follower
    dt = fp.dt_s
    wp = setup.waypoints
    heading = math.atan2(wp[1][1] - wp[0][1], wp[1][0] - wp[0][0])
    poses = initial_poses(form, Pose(float(wp[0][0]), float(wp[0][1]), heading))
    pilot = PathPilot(wp, setup.leader_speed_mps, fp.width_m, max_turn_rate_rps=setup.leader_turn_rate_rps)
    followers = {
        rid: make_controller(
            ControllerSetup(
                robot_id=rid,
                params=setup.follower_overrides.get(rid, fp),
                slot=slot,
                max_wheel_mps=setup.max_wheel_mps,
            )
        )
        for rid, slot in form.slots.items()
    }
    rngs = {rid: np.random.default_rng([setup.seed, rid]) for rid in followers}
    steps = int(round(setup.duration_s / dt))
    times = np.arange(steps) * dt
    rec_pose = {rid: np.zeros((steps, 3)) for rid in poses}
    rec_true = {rid: np.zeros((steps, 2)) for rid in followers}
    rec_meas = {rid: np.full((steps, 2), np.nan) for rid in followers}
    rec_est = {rid: np.full((steps, 2), np.nan) for rid in followers}
    rec_vn = {rid: np.full(steps, np.nan) for rid in followers}
    leader = form.leader
    for k in range(steps):
        cmds = {leader: pilot.step(poses[leader])}
        if pilot.finished:
            # The path is done: the run ends with it.
            steps = k
            break
        for rid, fol in followers.items():
            slot = form.slots[rid]
            m = next((m for m in observe(rid, poses, setup.camera, rngs[rid]) if m.robot_id == slot.reference), None)
            reading = None if m is None else MarkerReading(rho_m=m.rho_m, phi_rad=m.phi_rad, beta_rad=m.beta_rad)
            out = fol.step(FollowerInput(reading=reading, slot=slot, dt_s=dt))
            cmds[rid] = (out.left_mps, out.right_mps)
            rec_true[rid][k] = true_target(poses, form, rid)
            rec_vn[rid][k] = out.values.get("vn_mps", np.nan)
            if "measured_x_m" in out.values:
                rec_meas[rid][k] = from_body_frame(poses[rid], out.values["measured_x_m"], out.values["measured_y_m"])
            if out.target is not None:
                rec_est[rid][k] = from_body_frame(poses[rid], out.target.x_m, out.target.y_m)
        for rid, pose in poses.items():
            rec_pose[rid][k] = pose
        for rid, (vl, vr) in cmds.items():
            poses[rid] = kinematics.step(poses[rid], vl, vr, fp.width_m, dt)
    times = times[:steps]
    rec_pose = {rid: a[:steps] for rid, a in rec_pose.items()}
    rec_true, rec_meas, rec_est = ({rid: a[:steps] for rid, a in d.items()} for d in (rec_true, rec_meas, rec_est))
    rec_vn = {rid: a[:steps] for rid, a in rec_vn.items()}
    errors = {rid: np.hypot(*(rec_pose[rid][:, :2] - rec_true[rid]).T) for rid in followers}
    return ClosedLoopResult(times, rec_pose, rec_true, rec_meas, rec_est, rec_vn, errors)


# The paper's two-robot turning run (Fig. 6-7): straight, right turn, left turn.
PAPER_TURNING_PATH = ((0.0, 0.0), (0.0, 20.0), (20.0, 20.0), (20.0, 40.0))


def paper_turning_setup(seed: int = 0, **overrides: object) -> ClosedLoopSetup:
    form = Formation("two", {2: Slot(1, Point(-1.5, -1.5))})
    kwargs: dict[str, object] = {"waypoints": PAPER_TURNING_PATH, **overrides}
    return ClosedLoopSetup(formation=form, seed=seed, **kwargs)  # type: ignore[arg-type]
