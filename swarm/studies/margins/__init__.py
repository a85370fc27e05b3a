"""The claims as margins with 95% confidence intervals over seeds, and the
EKF's consistency (NEES), from runs in this process (studies.engine_run,
the lockstep runs' very trajectories):

- claim a against the leader's speed: dynamic V_N's largest and RMS
  formation error minus the better of static V_N 1.5 and 2's, seed by seed;
- claim c against observation drops: the EKF's target error over the raw
  reading's on the same ticks (those with a reading), with the ratio over
  every tick (the criterion of tests/system/test_claims.py) beside it;
- the EKF's mean NEES as shipped, under drops, under wheel noise it is not
  told of and told of, and with a tenth of its process noise;
- the partition-zone avoidance (eq. 11-13) on the paper's own formation
  change (triangle, line, triangle), with it and without it, and the rank
  swap's dependence on its slots, the leader's speed and the robots' size.

A claim's band is where the interval excludes zero.
"""

from __future__ import annotations

from formation_swarm.studies.margins.runs import Run

CLAIM_A = {"dynamic": "fig7_turn_vn_dynamic", "static 1.5": "fig6_turn_vn_1_5", "static 2": "fig6_turn_vn_2"}
SPEEDS = (1.35, 1.4, 1.45, 1.5, 1.55, 1.6, 1.65, 1.7)
DROPS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5)
EKF_SCENARIO = "fig9_ekf_noise"
WHEEL_NOISE = {"robot.wheel_noise_mps": 0.1}
# The process noise the wheel noise makes (docs/results.md, "telling the EKF").
TOLD = {"controller.ekf.q_pos_m": 0.13, "controller.ekf.q_phi_rad": 0.09}
# Every process-noise density divided by 10 (Q by 100): a filter planted overconfident.
OVERCONFIDENT = {
    "controller.ekf.q_pos_m": 0.002,
    "controller.ekf.q_phi_rad": 0.002,
    "controller.ekf.q_speed_mps": 0.05,
    "controller.ekf.q_turn_rps": 0.05,
}
# The NEES table's rows: (label, group of the runs).
NEES_ROWS = (
    ("as shipped", "drops 0%"),
    ("30% observation drops", "drops 30%"),
    ("40% observation drops", "drops 40%"),
    ("50% observation drops", "drops 50%"),
    ("wheel noise 0.1 m/s, not told", "wheel noise"),
    ("wheel noise 0.1 m/s, told (q_pos 0.13, q_phi 0.09)", "wheel noise, told"),
    ("process noise divided by 10 (planted overconfidence)", "overconfident"),
)


def speed_group(name: str, speed: float) -> str:
    return f"{name} at {speed:g} m/s"


def drop_group(drop: float) -> str:
    return f"drops {drop:.0%}"


def plan(seeds: range) -> list[Run]:
    """Every run of the study."""
    out = [
        Run(speed_group(name, v), scenario, {"leader.speed_mps": v}, s)
        for v in SPEEDS
        for name, scenario in CLAIM_A.items()
        for s in seeds
    ]
    out += [Run(drop_group(d), EKF_SCENARIO, {"links.obs_drop": d}, s) for d in DROPS for s in seeds]
    for group, ov in (("wheel noise", WHEEL_NOISE), ("wheel noise, told", {**WHEEL_NOISE, **TOLD})):
        out += [Run(group, EKF_SCENARIO, ov, s) for s in seeds]
    out += [Run("overconfident", EKF_SCENARIO, OVERCONFIDENT, s) for s in seeds]
    for label, scenario, ov in AVOIDANCE_CASES:
        for on in (True, False):
            out += [Run(avoidance_group(label, on), scenario, {**ov, "controller.avoidance": on}, s) for s in seeds]
    return out


def avoidance_group(label: str, on: bool) -> str:
    return f"{label}, eq. 11-13 {'on' if on else 'off'}"


def _rank_slots(ahead_m: float) -> dict[str, object]:
    """Both rank formations' slots moved ``ahead_m`` along the reference's heading (< 0: back)."""

    def slots(side: float) -> dict[str, object]:
        return {str(r): {"reference": r - 1, "offset": [side * 1.3, ahead_m]} for r in (2, 3)}

    return {"formations.rank_right.slots": slots(1.0), "formations.rank_left.slots": slots(-1.0)}


# (label, scenario, keys): the paper's triangle <-> line change, then the rank swap and its variations.
PAPER_CHANGE = (
    ("`fig11_obstacles`", "fig11_obstacles", {}),
    ("`fig11_shallow_triangle`", "fig11_shallow_triangle", {}),
)
RANK_SWAP = (
    ("as shipped (slots level, 1.5 m/s, 0.4 m robots)", "fig11_rank_swap", {}),
    ("slots 0.5 m back", "fig11_rank_swap", _rank_slots(-0.5)),
    ("slots 0.5 m ahead", "fig11_rank_swap", _rank_slots(0.5)),
    ("leader at 1.55 m/s", "fig11_rank_swap", {"leader.speed_mps": 1.55}),
    ("robots 0.30 m across", "fig11_rank_swap", {"robot.diameter_m": 0.3}),
)
AVOIDANCE_CASES = PAPER_CHANGE + RANK_SWAP
