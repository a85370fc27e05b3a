"""``swarm sim``: the paper's two-robot turning run in one process, no Zenoh."""

from __future__ import annotations

import argparse
import math
import sys

from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser, seconds, seed

SIM_MAX_S = 3600.0  # the paper's path takes 40 s; the recorded arrays grow with the duration


def _cmd_sim(args: argparse.Namespace) -> int:
    from formation_swarm.agents.follower import FollowerParams
    from formation_swarm.agents.fuzzy import SpeedMode
    from formation_swarm.spec.keys import ROBOT_KEYS
    from formation_swarm.studies.sim import paper_turning_setup, run

    mode = SpeedMode() if args.vn == "dynamic" else SpeedMode(float(args.vn))
    setup = paper_turning_setup(seed=args.seed, duration_s=args.duration, follower=FollowerParams(speed=mode))
    limit = ROBOT_KEYS["max_wheel_mps"].default  # the robots of swarm run's scenarios, checked the same way
    if mode.static_vn is not None and mode.static_vn + setup.follower.fuzzy.a_mps > limit:
        print(
            f"swarm sim: argument --vn: the fuzzy controller would command up to V_N + a = "
            f"{mode.static_vn + setup.follower.fuzzy.a_mps:g} m/s, above the robots' {limit:g} m/s "
            f"(robot.max_wheel_mps): at most {limit - setup.follower.fuzzy.a_mps:g}",
            file=sys.stderr,
        )
        return USAGE_ERROR
    if args.duration < setup.follower.dt_s:
        print(
            f"swarm sim: argument --duration: must be at least one control step ({setup.follower.dt_s:g} s), "
            f"got {args.duration:g}",
            file=sys.stderr,
        )
        return USAGE_ERROR
    print(
        f"paper two-robot turning run, one process: V_N {args.vn}, seed {args.seed}, "
        f"dt {setup.follower.dt_s} s, leader {setup.leader_speed_mps} m/s",
        flush=True,
    )
    result = run(setup)
    for rid in setup.formation.slots:
        print(
            f"follower R{rid}: {result.times_s[-1] + setup.follower.dt_s:.1f} s flown, formation error "
            f"RMS {result.rms(rid):.3f} m, max {result.max(rid):.3f} m"
        )
    return 0


def _vn(text: str) -> str:
    if text == "dynamic":
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be 'dynamic' or a speed > 0 in m/s, got {text!r}")
    return text


def add_sim(sub: argparse._SubParsersAction[Parser]) -> None:
    sim = sub.add_parser(
        "sim",
        help="the paper's two-robot turning run in one process, for quick controller checks",
        description="The paper's two-robot turning run (Fig. 6-7) in one Python loop, no Zenoh: the leader drives "
        "its path (straight, right turn, left turn), the follower flies the controller on a simulated camera. "
        "Prints the follower's formation error.",
    )
    sim.add_argument(
        "--vn",
        type=_vn,
        default="dynamic",
        help="the follower's normal speed V_N: 'dynamic' (FIS-2, the paper's two-stage controller) "
        "or a static value in m/s, e.g. 1.5 (default: dynamic)",
    )
    sim.add_argument(
        "--seed",
        type=seed,
        default=1,
        metavar="N",
        help="seed of the camera noise, an integer in [0, 2**63 - 1] (default: 1, the shipped scenarios' seed)",
    )
    sim.add_argument(
        "--duration",
        type=seconds(SIM_MAX_S),
        default=60.0,
        metavar="SECONDS",
        help=f"simulated time in s, at most {SIM_MAX_S:g}; the run ends earlier with the leader's path, "
        "at about 45 s (default: 60)",
    )
    sim.set_defaults(func=_cmd_sim, parser=sim)
