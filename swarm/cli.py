"""The ``swarm`` command."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence


def _cmd_sim(args: argparse.Namespace) -> int:
    from formation_swarm.agents.follower import FollowerParams
    from formation_swarm.agents.fuzzy import SpeedMode
    from formation_swarm.sim import paper_turning_setup, run

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


def _cmd_run(args: argparse.Namespace) -> int:
    from formation_swarm.launcher import KillAt, Launch, print_result
    from formation_swarm.proc import interrupt_on_stop_signals
    from formation_swarm.scenario import ScenarioError, parse_override

    try:
        kills = [KillAt.parse(spec) for spec in args.kill]
        overrides = dict(parse_override(text) for text in args.set)
        launch = Launch(
            args.scenario, mode=args.mode, seed=args.seed, out=args.out, overrides=overrides, logger=not args.no_logger,
            live=args.live, serve_web=args.serve_web, web_ports=(args.grpc_port, args.web_port), kills=kills,
        )  # fmt: skip
    except (ScenarioError, ValueError) as exc:
        print(f"swarm run: {exc}", file=sys.stderr)
        return 2
    print(f"[swarm] run {launch.run_id}: {launch.sc.name}, {len(launch.sc.robots)} robots, {args.mode}, "
          f"seed {launch.sc.seed}, folder {launch.run_dir}", flush=True)  # fmt: skip
    interrupt_on_stop_signals()  # Ctrl-C and SIGTERM stop the run cleanly
    try:
        launch.start()
    except KeyboardInterrupt:
        print(f"[swarm] interrupted while starting; every process stopped; folder {launch.run_dir}", flush=True)
        return 130
    with launch:
        result = launch.wait(timeout_s=args.timeout)
    print_result(result)
    return result.exit_code


def _cmd_scenarios(_args: argparse.Namespace) -> int:
    from formation_swarm import scenario

    known = scenario.shipped()
    width = max(map(len, known))
    for name, path in known.items():
        print(f"{name:<{width}}  {scenario.description(path)}")
    return 0


DELEGATED = {
    "world": ("formation_swarm.world.process", "the world process alone (router by default)"),
    "agent": ("formation_swarm.agents.process", "one robot's agent alone (client of a router)"),
    "logger": ("formation_swarm.logger", "the Rerun logger alone"),
    "router": ("formation_swarm.router", "a Zenoh router for agents on other machines"),
    "sweep": ("formation_swarm.sweep", "many lockstep runs: seeds x parameter values, in parallel, resumable"),
    "report": ("formation_swarm.report", "figures (PNG) and a markdown summary of a run folder"),
    "results": ("formation_swarm.results", "the baseline comparison table of docs/results.md"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="swarm", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sim = sub.add_parser("sim", help="one-process closed loop of the paper's two-robot turning run")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--duration", type=_positive_float, default=60.0, help="s (the path ends first)")
    sim.add_argument("--vn", type=_vn, default="dynamic", help="'dynamic' (FIS-2) or a static V_N, e.g. 1.5")
    sim.set_defaults(func=_cmd_sim)

    run = sub.add_parser("run", help="run a scenario, every robot its own process (world, logger, agents)")
    run.add_argument("scenario", help="a shipped scenario's name (see swarm scenarios) or a scenario file (TOML)")
    run.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    run.add_argument("--seed", type=int, default=None, help="overrides the scenario's seed")
    run.add_argument("--out", default=None, help="run folder (default runs/<run id>)")
    run.add_argument("--no-logger", action="store_true", help="no Rerun recording")
    run.add_argument(
        "--live", metavar="URL", help="also stream to a Rerun viewer, e.g. rerun+http://127.0.0.1:9876/proxy"
    )
    run.add_argument("--serve-web", action="store_true", help="also serve the Rerun web viewer")
    run.add_argument("--grpc-port", type=int, default=9876, help="--serve-web: the gRPC port (default 9876)")
    run.add_argument("--web-port", type=int, default=9090, help="--serve-web: the web viewer's port (default 9090)")
    run.add_argument("--kill", action="append", default=[], metavar="PROC@SECONDS",
                     help="fault injection: SIGKILL a process (agent-N, logger) at that sim time")  # fmt: skip
    run.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scenario key, e.g. leader.speed_mps=1.6 (repeatable)")  # fmt: skip
    run.add_argument("--timeout", type=float, default=None, help="wall-clock limit in s")
    run.set_defaults(func=_cmd_run)

    scenarios = sub.add_parser("scenarios", help="list the shipped scenarios with their descriptions")
    scenarios.set_defaults(func=_cmd_scenarios)

    for name, (_, text) in DELEGATED.items():
        sub.add_parser(name, help=text + f"; see swarm {name} --help")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in DELEGATED:
        import importlib

        return int(importlib.import_module(DELEGATED[argv[0]][0]).main(argv[1:]))
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
