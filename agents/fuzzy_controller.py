"""The paper's follower controller: EKF -> target -> FIS-2 -> FIS-1 -> wheels.

This is the whole controller of paper Fig. 4 with the EKF of section 3 (in
agents.tracking, shared with the l-psi baseline) and the collision
avoidance of section 2.2 (eq. 11-13; ``avoidance`` off, a follower goes
straight to its new slot), with no I/O, so the same object runs
inside an agent's role, the one-process simulator and the benchmarks. It
implements agents.controller's API.

Beyond the paper: the hold at a standing reference (agents.tracking), the
steering look-ahead (``lookahead_m``) and the wait ahead of the target. A
follower ahead of its target (signed rho < 0) is Close for FIS-1, which
drives both wheels at V_N - a >= 1 m/s straight on and does not steer; when
the target moves slower than that or elsewhere (the inner side of a turn, a
reference whose heading swings) the follower drives on, away from it. So
with ``wait_ahead`` a follower more than dn ahead of its target stops and
lets the target come, and drives on with the law once the target is within
d0 (docs/paper.md, "Beyond the paper: formations of many robots").
"""

from __future__ import annotations

from formation_swarm.agents import fuzzy as fz
from formation_swarm.agents.avoidance import Choice, select_target
from formation_swarm.agents.controller import ControllerSetup, FollowerOutput
from formation_swarm.agents.geometry import Point, TargetErrors, errors, lookahead_bearing
from formation_swarm.agents.tracking import Sight, TrackingController


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


class FuzzyController(TrackingController):
    """One follower flying the paper's fuzzy law."""

    def __init__(self, setup: ControllerSetup) -> None:
        super().__init__(setup)
        self._prev_choice = Choice.T0

    def _act(self, sight: Sight, measured: Point | None, ticks: int) -> FollowerOutput:
        if not self.p.avoidance:
            self.changing = False  # straight to the new slot: eq. 11-13 skipped
        choice, goal = self._target(sight)
        err = self._errors(goal, choice, sight.phi_rad)
        if self.changing and change_over(choice, err.rho_m, self.p.fuzzy):
            self.changing = False  # track T0 from now on
        self._prev_rho = err.rho_m
        self._prev_choice = choice
        if self._hold(err.rho_m, err.drho_m):
            return self._stand(err, sight, measured, choice, holding=True)
        if self.p.wait_ahead and not self.changing and self._wait(err.rho_m):
            return self._stand(err, sight, measured, choice, holding=False)
        return self._drive(err, sight, measured, choice, ticks)

    def _target(self, sight: Sight) -> tuple[Choice, Point]:
        """The point to steer to: the slot's target, or during a formation
        change the one eq. 13 picks (eq. 11-13)."""
        if not self.changing:
            return Choice.T0, sight.estimate
        sel = select_target(sight.leader, sight.phi_rad, self.offset, self.p.clearance_m)
        return sel.choice, sel.target

    def _errors(self, goal: Point, choice: Choice, phi_rad: float) -> TargetErrors:
        """alpha, rho and drho of eq. 4-6 toward ``goal``."""
        p = self.p
        # A switch of target makes rho jump; eq. 6 restarts from the new target.
        prev_rho = self._prev_rho if choice == self._prev_choice else None
        err = errors(goal, prev_rho, phi_rad)
        if p.drho_at_sign_change == "distance" and prev_rho is not None and prev_rho * err.rho_m < 0.0:
            err = TargetErrors(err.alpha_rad, err.rho_m, abs(err.rho_m) - abs(prev_rho))  # level with it: no jump
        if p.lookahead_m:
            err = TargetErrors(lookahead_bearing(goal, phi_rad, p.lookahead_m), err.rho_m, err.drho_m)
        return err

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

    def _drive(
        self, err: TargetErrors, sight: Sight, measured: Point | None, choice: Choice, ticks: int
    ) -> FollowerOutput:
        """FIS-2 (V_N) then FIS-1 (wheel speeds), paper section 4."""
        p = self.p
        vn, wheels = fz.control(err.alpha_rad, err.rho_m, err.drho_m, p.dt_s * ticks, p=p.fuzzy, mode=p.speed)
        return self._answer(
            (wheels.left_mps, wheels.right_mps), err, sight, vn_mps=vn, measured=measured, choice=choice
        )
