"""Sensor and actuator faults: what the world does to a robot's camera readings
and to the wheel speeds it executes, tick by tick (docs/faults.md).

The camera faults apply to followers only: in this model the leader has no
camera (it knows its own pose and senses obstacles with a separate range
sensor, which no fault here touches). The actuator faults and the wheel noise
apply to every robot, the leader included; the leader's pilot sees its true
pose, so they perturb what it does, not what it believes.

Every random draw of a fault comes from a generator of its own, keyed by the
run's seed, the robot and the fault (its text, and how many identical faults
come before it), never from the camera's stream: adding a fault changes
neither the camera noise of any robot nor the draws of the other faults, and a
run without faults draws exactly what it drew before faults existed. A
generator draws the same amount on every tick its fault is active, whatever
is in view or commanded, so its stream does not depend on the run's course.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from formation_swarm.common.faults import ACTUATOR, SENSOR, Fault
from formation_swarm.world.camera import CameraParams, MarkerReading, true_reading
from formation_swarm.world.kinematics import Pose, wrap_angle

# Tags of the generators' keys ([seed, robot, tag, ...]): the camera's own
# stream is [seed, robot], so none of these can meet it or each other.
SENSOR_TAG = 0x53454E53  # "SENS"
ACTUATOR_TAG = 0x41435455  # "ACTU"
WHEEL_NOISE_TAG = 0x4E4F4953  # "NOIS": robot.wheel_noise_mps

# What each camera fault counts, besides the ticks it was active for.
SENSOR_EFFECT = {"blackout": "blacked_out", "range": "cut", "outliers": "replaced", "bias": "biased"}
# Camera faults are applied in this order, whatever the schedule's: what the
# camera sees (blackout, range), then what it reads (outliers, then bias: a
# miscalibrated camera offsets a wrong detection too).
_SENSOR_ORDER = ("blackout", "range", "outliers", "bias")
_WHEELS = {"left": (True, False), "right": (False, True), "both": (True, True)}


def fault_rng(seed: int, robot_id: int, tag: int, fault: Fault, occurrence: int) -> np.random.Generator:
    """The generator of one fault on one robot (``occurrence``: identical faults before it)."""
    text = hashlib.blake2b(str(fault).encode(), digest_size=4).digest()
    return np.random.default_rng([seed, robot_id, tag, int.from_bytes(text, "little"), occurrence + 1])


@dataclass
class FaultEffect:
    """One fault on one robot: its generator (if it draws) and what it did: the
    ticks it was active for, and its effect (readings blacked out / cut /
    replaced / biased; for an actuator fault, the ticks on which the robot was
    commanded to move)."""

    fault: Fault
    rng: np.random.Generator | None = None
    ticks: int = 0
    effect: int = 0


def _effects(faults: Sequence[Fault], draws: str, *, seed: int, robot_id: int, tag: int) -> list[FaultEffect]:
    """One FaultEffect per fault, with a generator for the faults of kind ``draws``."""
    seen: dict[Fault, int] = {}
    out = []
    for f in faults:
        n = seen.get(f, 0)
        seen[f] = n + 1
        out.append(FaultEffect(f, fault_rng(seed, robot_id, tag, f, n) if f.kind == draws else None))
    return out


class CameraFaults:
    """The sensor faults of one follower's camera."""

    def __init__(self, faults: Sequence[Fault], *, seed: int, robot_id: int, dt_s: float, camera: CameraParams) -> None:
        self.robot_id = robot_id
        self.dt_s = dt_s
        self.camera = camera
        mine = [f for f in faults if f.group == SENSOR and f.applies_to(robot_id)]
        mine.sort(key=lambda f: _SENSOR_ORDER.index(f.kind))  # stable: schedule order within a kind
        self.effects = _effects(mine, "outliers", seed=seed, robot_id=robot_id, tag=SENSOR_TAG)

    def apply(self, tick: int, poses: Mapping[int, Pose], readings: list[MarkerReading]) -> list[MarkerReading]:
        """The readings of tick ``tick`` once this camera's active faults are applied."""
        active = [e for e in self.effects if e.fault.active(tick, self.dt_s)]
        if not active:
            return readings
        observer = poses[self.robot_id]
        others = [rid for rid in sorted(poses) if rid != self.robot_id]
        range_m = min([self.camera.range_m] + [e.fault.param("m") for e in active if e.fault.kind == "range"])
        half_fov = 0.5 * self.camera.fov_rad
        out = list(readings)
        for e in active:
            f = e.fault
            e.ticks += 1
            if f.kind == "blackout":
                e.effect += len(out)
                out = []
            elif f.kind == "range":
                # On the true distance, as the camera decides what is in range.
                kept = [
                    m
                    for m in out
                    if true_reading(observer, poses[m.robot_id], self.camera.marker_offset_m)[0] <= f.param("m")
                ]
                e.effect += len(out) - len(kept)
                out = kept
            elif f.kind == "outliers" and e.rng is not None:
                draws = e.rng.random((len(others), 4)).tolist()  # every robot, in view or not
                row = {rid: i for i, rid in enumerate(others)}
                p = f.param("p")
                for j, m in enumerate(out):
                    u, rho, phi, beta = draws[row[m.robot_id]]
                    if u < p:  # uniform within the range and the field of view
                        out[j] = MarkerReading(
                            m.robot_id, rho * range_m, math.pi * (2.0 * phi - 1.0), half_fov * (2.0 * beta - 1.0)
                        )
                        e.effect += 1
            elif f.kind == "bias":
                d_rho = f.param("rho_m")
                d_phi, d_beta = math.radians(f.param("phi_deg")), math.radians(f.param("beta_deg"))
                out = [
                    MarkerReading(
                        m.robot_id,
                        max(0.0, m.rho_m + d_rho),
                        wrap_angle(m.phi_rad + d_phi),
                        wrap_angle(m.beta_rad + d_beta),
                    )
                    for m in out
                ]
                e.effect += len(out)
        return out


class Wheels:
    """What one robot's wheels turn for what they are told: bias, slip, noise,
    stuck wheels, then the motors' limit."""

    def __init__(
        self,
        faults: Sequence[Fault],
        *,
        seed: int,
        robot_id: int,
        dt_s: float,
        noise_sigma_mps: float,
        max_wheel_mps: float,
    ) -> None:
        self.dt_s = dt_s
        self.max_wheel_mps = max_wheel_mps
        mine = [f for f in faults if f.group == ACTUATOR and f.applies_to(robot_id)]
        self.effects = _effects(mine, "wheel_noise", seed=seed, robot_id=robot_id, tag=ACTUATOR_TAG)
        self.noise_sigma_mps = noise_sigma_mps
        self.noise_rng = np.random.default_rng([seed, robot_id, WHEEL_NOISE_TAG]) if noise_sigma_mps > 0 else None

    def turn(self, tick: int, left_mps: float, right_mps: float) -> tuple[float, float]:
        """The wheel speeds (m/s) the robot turns on tick ``tick`` when commanded these.

        In order: bias (v * (1 + b)), slip (v * (1 - fraction)), Gaussian noise,
        the motors' limit; a stuck wheel does not turn, noise or not. A robot
        at rest (command (0, 0): stopped, stale or dead) stays at rest: a motor
        told to stand still does not jitter.
        """
        if not self.effects and self.noise_rng is None:
            return left_mps, right_mps
        moving = left_mps != 0.0 or right_mps != 0.0
        noise_l = noise_r = 0.0
        if self.noise_rng is not None:  # drawn every tick, moving or not
            n_l, n_r = self.noise_rng.standard_normal(2).tolist()
            noise_l, noise_r = self.noise_sigma_mps * n_l, self.noise_sigma_mps * n_r
        stuck_l = stuck_r = False
        vl, vr = left_mps, right_mps
        for e in self.effects:
            f = e.fault
            if not f.active(tick, self.dt_s):
                continue
            e.ticks += 1
            e.effect += moving
            if f.kind == "wheel_noise" and e.rng is not None:
                n_l, n_r = e.rng.standard_normal(2).tolist()
                sigma = f.param("sigma_mps")
                noise_l += sigma * n_l
                noise_r += sigma * n_r
            elif f.kind == "wheel_bias":
                vl *= 1.0 + f.param("left")
                vr *= 1.0 + f.param("right")
            elif f.kind == "slip":
                on_l, on_r = _WHEELS[f.param("wheel")]
                keep = 1.0 - f.param("fraction")
                vl, vr = (vl * keep if on_l else vl), (vr * keep if on_r else vr)
            elif f.kind == "stuck":
                on_l, on_r = _WHEELS[f.param("wheel")]
                stuck_l, stuck_r = stuck_l or on_l, stuck_r or on_r
        if not moving:
            return 0.0, 0.0
        lim = self.max_wheel_mps
        vl = 0.0 if stuck_l else min(max(vl + noise_l, -lim), lim)
        vr = 0.0 if stuck_r else min(max(vr + noise_r, -lim), lim)
        return vl, vr


def counts_table(per_robot: Mapping[int, Sequence[FaultEffect]], effect: Mapping[str, str] | str) -> dict:
    """``{fault text: {robot: {"ticks": n, effect: k}}}`` for the summary
    (identical faults on one robot add up under their common text)."""
    out: dict[str, dict[str, dict[str, int]]] = {}
    for rid in sorted(per_robot):
        for e in per_robot[rid]:
            name = effect if isinstance(effect, str) else effect[e.fault.kind]
            slot = out.setdefault(str(e.fault), {}).setdefault(str(rid), {"ticks": 0, name: 0})
            slot["ticks"] += e.ticks
            slot[name] += e.effect
    return out
