"""The separation-bearing (l-psi) baseline as a follower controller.

The law (agents.lpsi.control) on the same EKF estimate the fuzzy controller
uses (agents.tracking): the reference's centre, heading, speed and turn
rate. It tracks its slot directly: no partition-zone avoidance during a
formation change (a change ends at once) and no wait ahead of the target
(the law slows down by itself); the hold at a standing reference applies.
It implements agents.controller's API.
"""

from __future__ import annotations

import math

from formation_swarm.agents.avoidance import Choice
from formation_swarm.agents.controller import FollowerOutput
from formation_swarm.agents.geometry import Point, errors
from formation_swarm.agents.lpsi import control
from formation_swarm.agents.tracking import Sight, TrackingController


class LpsiController(TrackingController):
    """One follower flying the l-psi law."""

    def _act(self, sight: Sight, measured: Point | None, ticks: int) -> FollowerOutput:
        p = self.p
        v_ref, w_ref = (float(v) for v in self.ekf.state[3:5]) if p.use_ekf else (0.0, 0.0)
        err = errors(sight.estimate, self._prev_rho, sight.phi_rad)
        self.changing = False
        self._prev_rho = err.rho_m
        if self._hold(err.rho_m, err.drho_m):
            return self._stand(err, sight, measured, Choice.T0, holding=True)
        wheels = control(sight.leader, sight.phi_rad, v_ref, w_ref, offset=self.offset, width_m=p.width_m, p=p.lpsi)
        # No V_N in this law.
        return self._answer(wheels, err, sight, vn_mps=math.nan, measured=measured, choice=Choice.T0)
