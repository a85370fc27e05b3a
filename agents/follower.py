"""A follower's per-tick brain, pure: reading -> EKF -> target -> fuzzy -> wheels.

``law = "lpsi"`` swaps the fuzzy controller for the separation-bearing
baseline (agents.lpsi) on the same EKF estimate; that baseline tracks its
slot directly (no partition-zone avoidance during formation changes).

This is the whole controller of paper Fig. 4 plus the EKF of section 3 and
the collision avoidance of section 2.2, with no I/O, so the same object runs
inside an agent process, the one-process simulator and the benchmarks.

On top of either law sits one rule that is not the paper's: the hold at a
standing reference (docs/paper.md, "Beyond the paper"). The fuzzy controller
never drives slower than V_N - a (1 m/s), so a follower whose reference has
stopped would drive past its target and away; instead, when the EKF says the
reference stands still, the follower stops at its target, and goes on when
the reference moves again. It is decided from the follower's own estimate
only, so a lockstep run stays reproducible; raw mode (no EKF) has no speed
estimate and no hold.

Under the fuzzy law a second rule of ours: the wait ahead of the target. A
follower ahead of its target (signed rho < 0) is Close for FIS-1, which
drives both wheels at V_N - a >= 1 m/s straight on and does not steer; when
the target moves slower than that or elsewhere (the inner side of a turn, a
reference whose heading swings) the follower drives on, away from it. So a
follower more than dn ahead of its target stops and lets the target come,
and drives on with the law once the target is within d0 (docs/paper.md,
"Beyond the paper: formations of many robots").
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from formation_swarm.agents import fuzzy as fz
from formation_swarm.agents.avoidance import Choice, select_target
from formation_swarm.agents.ekf import EkfParams, TargetEKF
from formation_swarm.agents.geometry import (
    Point,
    errors,
    leader_point,
    lookahead_bearing,
    target_from_reading,
    target_point,
)
from formation_swarm.agents.lpsi import LpsiParams
from formation_swarm.agents.lpsi import control as lpsi_control
from formation_swarm.common.checks import finite, non_negative, positive

LAWS = ("fuzzy", "lpsi")
# Eq. 6 where the signed rho of eq. 5 changes sign (docs/paper.md, eq. 5): "signed", as printed, takes the
# jump of 2 |rho|; "distance" takes the change of |rho| there, which is what the follower moved.
DRHO_AT_SIGN_CHANGE = ("signed", "distance")


@dataclass(frozen=True)
class FollowerParams:
    width_m: float = 0.5
    marker_offset_m: float = 0.1
    dt_s: float = 0.05
    clearance_m: float = 1.0
    # Without a reading for this long the follower stops and waits.
    lost_after_s: float = 1.0
    fuzzy: fz.FuzzyParams = field(default_factory=fz.FuzzyParams)
    speed: fz.SpeedMode = field(default_factory=fz.SpeedMode)
    ekf: EkfParams = field(default_factory=EkfParams)
    use_ekf: bool = True
    law: str = "fuzzy"  # or "lpsi", the baseline
    drho_at_sign_change: str = "signed"  # or "distance" (DRHO_AT_SIGN_CHANGE)
    lpsi: LpsiParams = field(default_factory=LpsiParams)
    # The hold at a standing reference (not the paper's; docs/paper.md): the
    # reference stands still once the mean of the EKF's estimate of its speed
    # over the last hold_after_s is below hold_speed_mps (0: never hold), and
    # moves again once that mean is above resume_speed_mps.
    hold_speed_mps: float = 0.1
    resume_speed_mps: float = 0.3
    hold_after_s: float = 0.5
    # The wait ahead of the target (not the paper's; docs/paper.md): off, the
    # paper's follower drives on at V_N - a when it is ahead of its target.
    wait_ahead: bool = False
    # The steering look-ahead (not the paper's; docs/paper.md): the fuzzy law's
    # heading error alpha is the bearing of the point this far ahead of the
    # target along the reference's heading; 0: of the target, as the paper's.
    lookahead_m: float = 0.0

    def __post_init__(self) -> None:
        if self.law not in LAWS:
            raise ValueError(f"law must be one of {', '.join(map(repr, LAWS))}, got {self.law!r}")
        if self.drho_at_sign_change not in DRHO_AT_SIGN_CHANGE:
            raise ValueError(
                f"drho_at_sign_change must be one of {', '.join(map(repr, DRHO_AT_SIGN_CHANGE))}, "
                f"got {self.drho_at_sign_change!r}"
            )
        positive("width_m", self.width_m)
        non_negative("marker_offset_m", self.marker_offset_m)
        positive("dt_s", self.dt_s)
        positive("clearance_m", self.clearance_m)
        positive("lost_after_s", self.lost_after_s)
        non_negative("hold_speed_mps", self.hold_speed_mps)
        if not finite("resume_speed_mps", self.resume_speed_mps) >= self.hold_speed_mps:
            raise ValueError(
                f"resume_speed_mps must be >= hold_speed_mps ({self.hold_speed_mps!r}), got {self.resume_speed_mps!r}"
            )
        positive("hold_after_s", self.hold_after_s)
        non_negative("lookahead_m", self.lookahead_m)


class Decision(NamedTuple):
    """What the follower did this tick, for the command and the telemetry."""

    left_mps: float
    right_mps: float
    vn: float
    alpha_rad: float
    rho_m: float
    drho_m: float
    measured: Point | None  # target from this tick's raw reading (eq. 1-2)
    estimate: Point | None  # target from the EKF
    estimate_cov: np.ndarray | None
    steering_to: Choice
    changing: bool
    holding: bool = False  # stopped at its standing reference (vn is then 0)
    waiting: bool = False  # stopped more than dn ahead of its target, for it to come (vn is then 0)


def change_over(choice: Choice, rho_m: float, fuzzy: fz.FuzzyParams) -> bool:
    """Whether a formation change ends this tick (docs/paper.md, eq. 13).

    The paper gives no end: eq. 13 alone keeps a follower at T3 for ever.
    Ours: when eq. 13 picks T0 (the new slot is the nearer), or at T3 within
    d1 (the paper's "maximum distance error tolerance", the top of Enough).
    Within dn instead, measured on fig11_obstacles (seeds 1-3), the changes
    back to the triangle last 2.8-3.0 s (R2) and 12.4-13.2 s (R3) instead of
    one tick, and R3's RMS error doubles (1.04-1.06 m -> 1.97-2.02 m).
    """
    return choice is Choice.T0 or (choice is Choice.T3 and abs(rho_m) <= fuzzy.d1_m)


class Follower:
    """One follower: holds its formation slot, EKF and last errors."""

    def __init__(self, params: FollowerParams, offset: Point) -> None:
        self.p = params
        self.offset = Point(float(offset[0]), float(offset[1]))
        self.ekf = TargetEKF(params.ekf, params.marker_offset_m, params.width_m)
        self._last_cmd = (0.0, 0.0)
        self._prev_rho: float | None = None
        self._prev_choice = Choice.T0
        self._since_reading_s = math.inf
        self._raw: tuple[float, float, float] | None = None
        self._predicted = False
        self.changing = False
        # The EKF's estimates of the reference's speed over the last hold_after_s.
        window = max(1, round(params.hold_after_s / params.dt_s))
        self._speeds: collections.deque[float] = collections.deque(maxlen=window)
        self.holding = False
        self.waiting = False

    def set_offset(self, offset: Point) -> None:
        """A new formation slot: start the collision-avoiding change (sec. 2.2)."""
        new = Point(float(offset[0]), float(offset[1]))
        if new != self.offset:
            self.offset = new
            self.changing = True

    def new_reference(self) -> None:
        """The formation names another reference robot: forget the old one (its
        EKF estimate, rho, speeds); the next reading of the new one starts afresh."""
        self.ekf.reset()
        self._predicted = False
        self._prev_rho = None
        self._raw = None
        self._since_reading_s = math.inf
        self._speeds.clear()
        self.holding = False
        self.waiting = False

    def prepare(self) -> None:
        """The EKF's prediction for the next tick (from the command just sent),
        run now; ``step`` then only corrects. An agent calls it while it waits
        for the next observation, which takes it off the tick's critical path.
        The result is the same as letting ``step`` predict."""
        if self.p.use_ekf and not self._predicted:
            self.ekf.predict(self._last_cmd[0], self._last_cmd[1], self.p.dt_s)
            self._predicted = True

    def step(self, reading: tuple[float, float, float] | None, ticks: int = 1) -> Decision:
        """One tick. ``reading`` is the reference's (rho_r, phi, beta), or None.

        ``ticks``: the ticks since the last step (1 but where the agent skipped
        observations, in real time when it could not keep up, or was frozen).
        The EKF then predicts over them with the command the robot kept (in
        one step: an agent that fell behind gets no more work for it), and
        drho (eq. 6) is taken over their time, so neither the reference's
        speed nor the approach rate looks faster than it is.
        A gap longer than ``lost_after_s`` restarts the filter from this
        reading, as a lost reference does: the robot stood still for part of
        it (the world stops a robot on a stale command), which the filter
        cannot know."""
        p = self.p
        if isinstance(ticks, bool) or not isinstance(ticks, int) or ticks < 1:
            raise ValueError(f"ticks must be an integer >= 1, got {ticks!r}")
        measured = None
        if reading is not None:
            measured = target_from_reading(reading[0], reading[1], reading[2], p.marker_offset_m, self.offset)
            self._since_reading_s = 0.0
            self._raw = (float(reading[0]), float(reading[1]), float(reading[2]))
        else:
            self._since_reading_s += p.dt_s * ticks
        if ticks > 1 and ticks * p.dt_s > p.lost_after_s:
            self.ekf.reset()
            self._prev_rho = None
            self._speeds.clear()
            ticks = 1
        if p.use_ekf:
            self.prepare()
            if ticks > 1:  # the skipped ticks, on the command the robot kept: one step, however many
                self.ekf.predict(self._last_cmd[0], self._last_cmd[1], p.dt_s * (ticks - 1))
            self._predicted = False
            starting = not self.ekf.initialized
            self.ekf.update(reading)
            if starting or not self.ekf.initialized:
                self._speeds.clear()  # a filter that (re)starts knows only its prior speed, 0
            else:
                self._speeds.append(self.ekf.speed_mps)
        if self._since_reading_s > p.lost_after_s or self._raw is None or (p.use_ekf and not self.ekf.initialized):
            return self._stop(measured)  # lost, never seen, or the EKF restarts (diverged)

        if p.use_ekf:
            leader, phi = self.ekf.leader()
            estimate, cov = self.ekf.target(self.offset)
        else:
            # Raw mode (no EKF): act on the latest reading as it is.
            rho_r, phi, beta = self._raw
            leader = leader_point(rho_r, phi, beta, p.marker_offset_m)
            estimate, cov = target_point(leader, phi, self.offset), None
        if p.law == "lpsi":
            return self._lpsi(leader, phi, measured, estimate, cov)
        choice = Choice.T0
        goal = estimate
        if self.changing:
            sel = select_target(leader, phi, self.offset, p.clearance_m)
            choice, goal = sel.choice, sel.target
        # A switch of target makes rho jump; eq. 6 restarts from the new target.
        prev_rho = self._prev_rho if choice == self._prev_choice else None
        err = errors(goal, prev_rho, phi)
        if p.drho_at_sign_change == "distance" and prev_rho is not None and prev_rho * err.rho_m < 0.0:
            err = err._replace(drho_m=abs(err.rho_m) - abs(prev_rho))  # level with the target: no jump
        if p.lookahead_m:
            err = err._replace(alpha_rad=lookahead_bearing(goal, phi, p.lookahead_m))
        if self.changing and change_over(choice, err.rho_m, p.fuzzy):
            self.changing = False  # track T0 from now on
        self._prev_rho = err.rho_m
        self._prev_choice = choice
        if self._hold(err.rho_m, err.drho_m):
            self._last_cmd = (0.0, 0.0)
            return Decision(
                0.0,
                0.0,
                0.0,
                err.alpha_rad,
                err.rho_m,
                err.drho_m,
                measured,
                estimate,
                cov,
                choice,
                self.changing,
                holding=True,
            )
        if p.wait_ahead and not self.changing and self._wait(err.rho_m):
            self._last_cmd = (0.0, 0.0)
            return Decision(
                0.0,
                0.0,
                0.0,
                err.alpha_rad,
                err.rho_m,
                err.drho_m,
                measured,
                estimate,
                cov,
                choice,
                self.changing,
                waiting=True,
            )
        vn, wheels = fz.control(err.alpha_rad, err.rho_m, err.drho_m, p.dt_s * ticks, p.fuzzy, p.speed)
        self._last_cmd = (wheels.left_mps, wheels.right_mps)
        return Decision(
            wheels.left_mps,
            wheels.right_mps,
            vn,
            err.alpha_rad,
            err.rho_m,
            err.drho_m,
            measured,
            estimate,
            cov,
            choice,
            self.changing,
        )

    def reference_speed(self) -> float:
        """The mean of the EKF's estimates of the reference's speed over the last
        hold_after_s, m/s (inf until there are that many since the filter started)."""
        n = len(self._speeds)
        return abs(sum(self._speeds)) / n if n == self._speeds.maxlen else math.inf

    def _hold(self, rho_m: float, drho_m: float) -> bool:
        """Whether to hold this tick (docs/paper.md, "Beyond the paper").

        With the reference standing still, the follower stops once it is at its
        target: within d0 of it, level with it or past it (signed rho <= d0), or
        at its closest approach within dn (rho no longer falling). It goes on
        when the reference moves again, or when the target is more than d1
        ahead, which it then approaches with its law and holds at again.
        """
        fzp = self.p.fuzzy
        speed = self.reference_speed()
        if self.holding:
            self.holding = speed <= self.p.resume_speed_mps and rho_m <= fzp.d1_m
        else:
            self.holding = speed < self.p.hold_speed_mps and (
                rho_m <= fzp.d0_m or (rho_m <= fzp.dn_m and drho_m >= 0.0)
            )
        return self.holding

    def _wait(self, rho_m: float) -> bool:
        """Whether to wait for the target this tick (the fuzzy law only; the
        l-psi law slows down by itself).

        rho < 0 is Close for FIS-1: both wheels at V_N - a, at least
        vn_min - a (1 m/s), no steering, so a follower ahead of its target
        gets farther ahead of any target slower than that. More than dn ahead
        (beyond Close's "minimum error" band, which the paper's follower
        drives through) it stops; it drives on once the target is within d0
        (the paper's minimum error). The band between them keeps the
        estimate's noise from starting and ending a wait every tick.
        """
        fzp = self.p.fuzzy
        self.waiting = rho_m < -fzp.d0_m if self.waiting else rho_m < -fzp.dn_m
        return self.waiting

    def _lpsi(
        self, leader: Point, phi: float, measured: Point | None, estimate: Point, cov: np.ndarray | None
    ) -> Decision:
        p = self.p
        v_ref, w_ref = (float(v) for v in self.ekf.state[3:5]) if p.use_ekf else (0.0, 0.0)
        err = errors(estimate, self._prev_rho, phi)
        self.changing = False
        self._prev_rho = err.rho_m
        if self._hold(err.rho_m, err.drho_m):
            self._last_cmd = (0.0, 0.0)
            return Decision(
                0.0,
                0.0,
                0.0,
                err.alpha_rad,
                err.rho_m,
                err.drho_m,
                measured,
                estimate,
                cov,
                Choice.T0,
                False,
                holding=True,
            )
        left, right = lpsi_control(leader, phi, v_ref, w_ref, self.offset, p.width_m, p.lpsi)
        self._last_cmd = (left, right)
        return Decision(
            left, right, math.nan, err.alpha_rad, err.rho_m, err.drho_m, measured, estimate, cov, Choice.T0, False
        )

    def _stop(self, measured: Point | None) -> Decision:
        self._last_cmd = (0.0, 0.0)
        self.holding = False
        self.waiting = False
        self._prev_rho = None
        nan = math.nan
        return Decision(0.0, 0.0, nan, nan, nan, nan, measured, None, None, Choice.T0, self.changing)
