"""The ``swarm`` command."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence


def _cmd_sim(args: argparse.Namespace) -> int:
    from agents.follower import FollowerParams
    from agents.fuzzy import SpeedMode
    from swarm.sim import paper_turning_setup, run

    mode = SpeedMode() if args.vn == "dynamic" else SpeedMode(float(args.vn))
    setup = paper_turning_setup(seed=args.seed, duration_s=args.duration, follower=FollowerParams(speed=mode))
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


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def _vn(text: str) -> str:
    if text == "dynamic":
        return text
    try:
        _positive_float(text)
    except (ValueError, argparse.ArgumentTypeError):
        raise argparse.ArgumentTypeError(f"must be 'dynamic' or a positive number, got {text!r}") from None
    return text


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="swarm", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sim = sub.add_parser("sim", help="one-process closed loop of the paper's two-robot turning run")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--duration", type=_positive_float, default=60.0, help="s (the path ends first)")
    sim.add_argument("--vn", type=_vn, default="dynamic", help="'dynamic' (FIS-2) or a static V_N, e.g. 1.5")
    sim.set_defaults(func=_cmd_sim)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
