"""A follower's parameters: the scenario's ``[controller]`` table, checked.

Both control laws read them (agents.fuzzy_controller, agents.lpsi_controller):
the EKF, the hold at a standing reference and the lost reading are shared;
``law`` names the law a follower flies (agents.follower.make_controller):
one of ``LAWS``, or a law of the user's (agents.laws) with its own
parameters in ``law_params``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from formation_swarm.agents import fuzzy as fz
from formation_swarm.agents.ekf import EkfParams
from formation_swarm.agents.lpsi import LpsiParams
from formation_swarm.common.checks import finite, non_negative, positive

LAWS = ("fuzzy", "lpsi")  # the built-in laws
# Eq. 6 where the signed rho of eq. 5 changes sign (docs/paper.md, eq. 5): "signed", as printed, takes the
# jump of 2 |rho|; "distance" takes the change of |rho| there, which is what the follower moved.
DRHO_AT_SIGN_CHANGE = ("signed", "distance")


@dataclass(frozen=True)
class FollowerParams:
    width_m: float = 0.5
    marker_offset_m: float = 0.1
    dt_s: float = 0.05
    clearance_m: float = 1.0
    # The partition-zone avoidance during a formation change (eq. 11-13); off,
    # a follower goes straight to its new slot (the ablation of docs/results.md).
    avoidance: bool = True
    # Without a reading for this long the follower stops and waits.
    lost_after_s: float = 1.0
    fuzzy: fz.FuzzyParams = field(default_factory=fz.FuzzyParams)
    speed: fz.SpeedMode = field(default_factory=fz.SpeedMode)
    ekf: EkfParams = field(default_factory=EkfParams)
    use_ekf: bool = True
    law: str = "fuzzy"  # or "lpsi", the baseline, or a law of the user's (agents.laws)
    # A user's law's parameters ([controller.params], checked against its class), as (name, value) pairs.
    law_params: tuple[tuple[str, bool | int | float | str], ...] = ()
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
        if not isinstance(self.law, str) or not self.law:
            raise ValueError(f"law must be one of {', '.join(map(repr, LAWS))} or a law's name, got {self.law!r}")
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
