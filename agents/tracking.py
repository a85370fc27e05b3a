"""What both built-in follower controllers share: the reference, tracked.

Each tick the reading of the reference's marker goes to the EKF of section 3
(or, in raw mode, is used as it is); the tracker says where the reference
and the target are, stops the robot when the reference is lost (no reading
for ``lost_after_s``) or the filter restarts, and decides the hold at a
standing reference. A law turns that sight into its answer (wheel speeds,
the target, named values) in ``_act``: agents.fuzzy_controller (the
paper's) and agents.lpsi_controller.

The hold is not the paper's (docs/paper.md, "Beyond the paper"). The fuzzy
controller never drives slower than V_N - a (1 m/s), so a follower whose
reference has stopped would drive past its target and away; instead, when
the EKF says the reference stands still, the follower stops at its target,
and goes on when the reference moves again. It is decided from the
follower's own estimate only, so a lockstep run stays reproducible; raw
mode (no EKF) has no speed estimate and no hold.
"""

from __future__ import annotations

import collections
import math
from typing import NamedTuple

import numpy as np

from formation_swarm.agents.avoidance import Choice
from formation_swarm.agents.controller import (
    HOLDING,
    LOST,
    WAITING,
    ControllerSetup,
    FollowerInput,
    FollowerOutput,
    TargetEstimate,
)
from formation_swarm.agents.ekf import TargetEKF
from formation_swarm.agents.geometry import (
    MarkerReading,
    Point,
    TargetErrors,
    leader_point,
    target_from_reading,
    target_point,
)


class Sight(NamedTuple):
    """The reference as the follower sees it this tick, in its own frame."""

    leader: Point  # the reference's centre
    phi_rad: float  # the reference's heading relative to ours
    estimate: Point  # the target (eq. 2-3)
    cov: np.ndarray | None  # the target's covariance (None in raw mode)


class TrackingController:
    """A follower's state between ticks and the controller API's ``step``;
    a subclass is one law (``_act``)."""

    def __init__(self, setup: ControllerSetup) -> None:
        params = setup.params
        self.p = params
        self.offset = _point(setup.slot.offset)
        self.ekf = TargetEKF(params.ekf, params.marker_offset_m, params.width_m)
        self._last_cmd = (0.0, 0.0)
        self._prev_rho: float | None = None
        self._since_reading_s = math.inf
        self._raw: MarkerReading | None = None
        self._predicted = False
        self.changing = False
        # The EKF's estimates of the reference's speed over the last hold_after_s.
        window = max(1, round(params.hold_after_s / params.dt_s))
        self._speeds: collections.deque[float] = collections.deque(maxlen=window)
        self.holding = False
        self.waiting = False

    def step(self, inp: FollowerInput) -> FollowerOutput:
        """One tick (agents.controller's API).

        ``inp.ticks``: the ticks since the last step (1 but where the agent
        skipped observations, in real time when it could not keep up, or was
        frozen). The EKF then predicts over them with the command the robot
        kept (in one step: an agent that fell behind gets no more work for
        it), and drho (eq. 6) is taken over their time, so neither the
        reference's speed nor the approach rate looks faster than it is.
        A gap longer than ``lost_after_s`` restarts the filter from this
        reading, as a lost reference does: the robot stood still for part of
        it (the world stops a robot on a stale command), which the filter
        cannot know."""
        ticks = inp.ticks
        if isinstance(ticks, bool) or not isinstance(ticks, int) or ticks < 1:
            raise ValueError(f"ticks must be an integer >= 1, got {ticks!r}")
        if inp.new_reference:
            self.new_reference()
        self.offset = _point(inp.slot.offset)
        if inp.slot_moved:
            self.changing = True  # the collision-avoiding change (sec. 2.2) starts
        reading = inp.reading
        measured = self._read(reading, ticks)
        ticks = self._bridge(ticks)
        if self.p.use_ekf:
            self._filter(reading, ticks)
        sight = self._sight()
        if sight is None:
            return self._stop(measured)  # lost, never seen, or the EKF restarts (diverged)
        return self._act(sight, measured, ticks)

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

    # -- the steps of a tick ------------------------------------------------------

    def _read(self, reading: MarkerReading | None, ticks: int) -> Point | None:
        """Take this tick's reading: the target it shows (eq. 1-2), or None."""
        p = self.p
        if reading is None:
            self._since_reading_s += p.dt_s * ticks
            return None
        self._since_reading_s = 0.0
        self._raw = reading
        return target_from_reading(reading.rho_m, reading.phi_rad, reading.beta_rad, p.marker_offset_m, self.offset)

    def _bridge(self, ticks: int) -> int:
        """The ticks the filter predicts over: a gap longer than lost_after_s
        restarts it instead (then 1)."""
        p = self.p
        if ticks > 1 and ticks * p.dt_s > p.lost_after_s:
            self.ekf.reset()
            self._prev_rho = None
            self._speeds.clear()
            return 1
        return ticks

    def _filter(self, reading: MarkerReading | None, ticks: int) -> None:
        """The EKF's step (eq. 17-21), and the reference's speed it gives."""
        self.prepare()
        if ticks > 1:  # the skipped ticks, on the command the robot kept: one step, however many
            self.ekf.predict(self._last_cmd[0], self._last_cmd[1], self.p.dt_s * (ticks - 1))
        self._predicted = False
        starting = not self.ekf.initialized
        self.ekf.update(reading)
        if starting or not self.ekf.initialized:
            self._speeds.clear()  # a filter that (re)starts knows only its prior speed, 0
        else:
            self._speeds.append(self.ekf.speed_mps)

    def _sight(self) -> Sight | None:
        """Where the reference and the target are; None when the follower must stop."""
        p = self.p
        if self._since_reading_s > p.lost_after_s or self._raw is None or (p.use_ekf and not self.ekf.initialized):
            return None
        if p.use_ekf:
            leader, phi = self.ekf.leader()
            estimate, cov = self.ekf.target(self.offset)
            return Sight(leader=leader, phi_rad=phi, estimate=estimate, cov=cov)
        # Raw mode (no EKF): act on the latest reading as it is.
        raw = self._raw
        leader = leader_point(raw.rho_m, raw.phi_rad, raw.beta_rad, p.marker_offset_m)
        phi = raw.phi_rad
        return Sight(leader=leader, phi_rad=phi, estimate=target_point(leader, phi, self.offset), cov=None)

    def _act(self, sight: Sight, measured: Point | None, ticks: int) -> FollowerOutput:
        """The law: its answer from the sight of the reference."""
        raise NotImplementedError

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

    def _answer(
        self,
        wheels: tuple[float, float],
        err: TargetErrors,
        sight: Sight,
        *,
        vn_mps: float,
        measured: Point | None,
        choice: Choice,
        stop: str | None = None,
    ) -> FollowerOutput:
        """The tick's answer: ``wheels`` (left, right, m/s) commanded, the rest for the telemetry."""
        self._last_cmd = wheels
        cov = sight.cov
        target = TargetEstimate(
            x_m=sight.estimate[0],
            y_m=sight.estimate[1],
            cov_m2=None if cov is None else (float(cov[0, 0]), float(cov[0, 1]), float(cov[1, 1])),
        )
        values = self._values(err.rho_m, err.alpha_rad, vn_mps, choice, measured)
        return FollowerOutput(left_mps=wheels[0], right_mps=wheels[1], target=target, stop=stop, values=values)

    def _stand(
        self, err: TargetErrors, sight: Sight, measured: Point | None, choice: Choice, *, holding: bool
    ) -> FollowerOutput:
        """Stopped this tick, holding (else waiting), with the errors as they are."""
        stop = HOLDING if holding else WAITING
        return self._answer((0.0, 0.0), err, sight, vn_mps=0.0, measured=measured, choice=choice, stop=stop)

    def _stop(self, measured: Point | None) -> FollowerOutput:
        """Stopped without a sight of the reference: no target, no errors."""
        self._last_cmd = (0.0, 0.0)
        self.holding = False
        self.waiting = False
        self._prev_rho = None
        nan = math.nan
        values = self._values(nan, nan, nan, Choice.T0, measured)
        return FollowerOutput(left_mps=0.0, right_mps=0.0, stop=LOST, values=values)

    def _values(
        self, rho_m: float, alpha_rad: float, vn_mps: float, choice: Choice, measured: Point | None
    ) -> dict[str, float]:
        """The tick's named values (agents.controller.WIRE_VALUES, STATS_VALUES)."""
        values = {
            "rho_m": rho_m,
            "alpha_rad": alpha_rad,
            "vn_mps": vn_mps,
            "steering_to": float(choice),
            "changing": float(self.changing),
            "ekf_resets": float(self.ekf.resets),
        }
        if measured is not None:
            values["measured_x_m"], values["measured_y_m"] = measured
        return values


def _point(offset: Point) -> Point:
    return Point(float(offset[0]), float(offset[1]))
