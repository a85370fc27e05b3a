"""swarm: an emulator of vision-based leader-follower formation control, where
every robot is its own process and every exchange crosses Eclipse Zenoh.

The robots fly the controller of "Modeling of vision based robot formation
control using fuzzy logic controller and extended Kalman filter" (IJFIS 12(3),
2012): a camera sees the marker of the robot ahead, an EKF smooths what it
sees, and a two-stage fuzzy controller (FIS-2 sets the normal speed V_N, FIS-1
the wheel speeds) drives a differential-drive robot.

Start with:
  swarm scenarios                   the shipped scenarios
  swarm run fig11_obstacles         one run: world, logger and one process per robot
  swarm report runs/<run id>        figures and a summary of that run
  swarm COMMAND --help              what a command does, its flags, units and defaults
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

from formation_swarm.common.version import __version__
from formation_swarm.runtime.cliargs import (
    USAGE_ERROR,
    Parser,
    add_tls_arguments,
    integer,
    make_folder,
    port,
    rerun_url,
    seconds,
    seed,
    tls,
)

GRPC_PORT, WEB_PORT = 9876, 9090  # --serve-web's defaults: Rerun's own
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


def _run_flag_conflicts(args: argparse.Namespace) -> str | None:
    """What the run's flags contradict each other on, or None."""
    if args.no_logger and (args.live or args.serve_web):
        return f"argument {'--live' if args.live else '--serve-web'}: the logger does the streaming; drop --no-logger"
    for flag, value in (("--grpc-port", args.grpc_port), ("--web-port", args.web_port)):
        if value is not None and not args.serve_web:
            return f"argument {flag}: only used with --serve-web, got {flag} {value} alone"
    if args.rt_priority is not None and args.mode != "realtime":
        return f"argument --rt-priority: only used with --mode realtime, got it in {args.mode}"
    if args.serve_web and (args.grpc_port or GRPC_PORT) == (args.web_port or WEB_PORT):
        return f"arguments --grpc-port and --web-port: must differ, got {args.grpc_port or GRPC_PORT} for both"
    return None


def _cmd_run(args: argparse.Namespace) -> int:
    if conflict := _run_flag_conflicts(args):
        print(f"swarm run: {conflict} (see swarm run --help)", file=sys.stderr)
        return USAGE_ERROR
    import zenoh

    from formation_swarm.launch.launcher import KillAt, Launch, print_result
    from formation_swarm.launch.remote import HostError, parse_placement
    from formation_swarm.runtime.proc import interrupt_on_stop_signals
    from formation_swarm.spec.files import parse_overrides
    from formation_swarm.spec.scenario import ScenarioError

    try:
        kills = [KillAt.parse(spec) for spec in args.kill]
        overrides = parse_overrides(args.set)
        hosts = [h.strip() for h in (args.hosts or "").split(",") if h.strip()]
        launch = Launch(
            args.scenario,
            mode=args.mode,
            seed=args.seed,
            out=args.out,
            overrides=overrides,
            logger=not args.no_logger,
            live=args.live,
            serve_web=args.serve_web,
            kills=kills,
            faults=args.fault,
            web_ports=(args.grpc_port or GRPC_PORT, args.web_port or WEB_PORT),
            hosts=hosts,
            placement=parse_placement(args.place or ""),
            listen=args.listen,
            host_logins=args.host_logins,
            hosts_timeout_s=args.hosts_timeout,
            tls=tls(args),
            rt_priority=args.rt_priority,
        )
        if args.out is not None and not args.out.strip():
            raise ValueError("--out '': an empty name")
        if args.out is not None and (Path(args.out) / "summary.json").exists():
            raise ValueError(f"--out {args.out}: already holds a run (summary.json); give a new folder")
        make_folder("--out" if args.out else "run folder", launch.run_dir)  # last: nothing made for a bad input
    except (ScenarioError, ValueError) as exc:
        print(f"swarm run: {exc}", file=sys.stderr)
        return USAGE_ERROR
    print(
        f"[swarm] run {launch.run_id}: {launch.sc.name}, {len(launch.sc.robots)} robots, {args.mode}, "
        f"seed {launch.sc.seed}, folder {launch.run_dir}",
        flush=True,
    )
    interrupt_on_stop_signals()  # Ctrl-C and SIGTERM stop the run cleanly
    try:
        launch.start()
    except KeyboardInterrupt:
        print(f"[swarm] interrupted while starting; every process stopped; folder {launch.run_dir}", flush=True)
        return 130
    except zenoh.ZError as exc:  # the world never listened (start() has reaped every process): its log says why
        from formation_swarm.protocol.session import zenoh_reason

        print(
            f"swarm run: cannot reach the world at {launch.endpoint}: {zenoh_reason(exc)}; see "
            f"{launch.run_dir / 'logs'}",
            file=sys.stderr,
        )
        return 1
    except (HostError, ValueError) as exc:  # a host missing, refusing or unable to run a robot: every process reaped
        print(f"swarm run: {exc}; nothing left running; folder {launch.run_dir}", file=sys.stderr)
        return 1
    with launch:
        result = launch.wait(timeout_s=args.timeout)
    print_result(result)
    return result.exit_code


def _cmd_scenarios(_args: argparse.Namespace) -> int:
    from formation_swarm.spec import files as scenario

    known = scenario.shipped()
    width = max(map(len, known))
    for name, path in known.items():
        print(f"{name:<{width}}  {scenario.description(path)}")
    return 0


# Commands with their own parser in their own module: name -> (module, one-line summary).
DELEGATED = {
    "report": ("formation_swarm.report.build", "figures (PNG, SVG or PDF) and a markdown summary of a run's folder"),
    "export": (
        "formation_swarm.report.export",
        "a run's folder as a table, one row per robot per tick (CSV or Parquet)",
    ),
    "compare": (
        "formation_swarm.report.compare",
        "one figure overlaying several runs: formation error and trajectories",
    ),
    "sweep": (
        "formation_swarm.studies.sweep",
        "many lockstep runs of a scenario (seeds x parameter values), in parallel",
    ),
    "results": ("formation_swarm.studies.results", "recompute the baseline comparison table of docs/results.md"),
    "world": ("formation_swarm.nodes.world", "role: the world alone (physics, cameras, clock; a Zenoh router)"),
    "agent": ("formation_swarm.nodes.agent", "role: one robot's agent alone, a client of a router"),
    "logger": ("formation_swarm.nodes.logger", "role: the Rerun logger alone (to a file or a viewer)"),
    "router": ("formation_swarm.nodes.router", "role: a Zenoh router for agents on other machines"),
    "secure": ("formation_swarm.launch.secure", "credentials and access rules for a run spread over machines"),
    "host": ("formation_swarm.nodes.host", "serve this machine to runs started elsewhere (swarm run --hosts)"),
    "doctor": ("formation_swarm.launch.doctor", "check that the hosts of a run spread over machines are there and fit"),
}

RUN_EPILOG = """\
exit codes: 0 the run ended normally; 1 the world failed, a process failed
before tick 0 (its log's last lines are printed), or the run lost its leader
(or every follower) for good, a kill fault included; 2 a bad command line (one
line on stderr, nothing started); 124 --timeout; 130 interrupted (Ctrl-C).

examples:
  swarm run fig11_obstacles
  swarm run fig7_turn_vn_dynamic --seed 3 --set controller.vn=1.5 --out runs/static
  swarm run fig11_obstacles --mode realtime --serve-web     (then open http://127.0.0.1:9090)
  swarm run fig11_obstacles --fault "kill agent-3@20s"
  swarm run fig11_obstacles --fault "restart agent-2@20s after=1s" --fault "drop obs:3@10s for=5s p=0.5"
  (every fault kind: docs/faults.md)
"""


def _add_run(sub: argparse._SubParsersAction[Parser]) -> None:
    run = sub.add_parser(
        "run",
        help="run a scenario, every robot its own process (world, logger, agents)",
        description="Run one scenario on this machine: the world (physics, cameras, clock; also the Zenoh router), "
        "a Rerun logger and one process per robot. Progress and the metrics go to the console; the run folder gets "
        "the scenario as run, recording.rrd, summary.json and logs/.",
        epilog=RUN_EPILOG,
    )
    run.add_argument("scenario", help="a shipped scenario's name (see: swarm scenarios) or a scenario file (TOML)")
    run.add_argument(
        "--mode",
        choices=("lockstep", "realtime"),
        default="lockstep",
        help="lockstep: the world waits for every robot each tick, reproducible and as fast as the "
        "machine goes; realtime: the world steps on the wall clock, in Linux's real-time "
        "scheduling class where the machine allows it (root, CAP_SYS_NICE or an RLIMIT_RTPRIO of "
        "10: see swarm world --rt-priority; the result line says when it did not) "
        "(default: lockstep)",
    )
    run.add_argument(
        "--rt-priority",
        type=integer(0, 99),
        default=None,
        metavar="0-99",
        help="realtime: the world's real-time priority, or 0 to keep it in the normal class "
        "(default: swarm world's, 10)",
    )
    run.add_argument(
        "--seed",
        type=seed,
        default=None,
        metavar="N",
        help="seed of every random draw (camera noise, link drops, the faults' draws), "
        "an integer in [0, 2**63 - 1] (default: the scenario's run.seed)",
    )
    run.add_argument(
        "--out", default=None, metavar="DIR", help="the run folder, created if needed (default: runs/<run id>)"
    )
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one scenario key, e.g. leader.speed_mps=1.6 or controller.vn=dynamic (repeatable)",
    )
    run.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="'KIND TARGET@TIME ...'",
        help="schedule a fault, e.g. 'kill agent-3@20s', 'freeze agent-2@10s for=3s', "
        "'partition 2,3@12s for=15s', 'wheel_noise *@0s sigma_mps=0.1' (repeatable; added to the "
        "scenario's [[faults]]; every kind: docs/faults.md)",
    )
    run.add_argument(
        "--kill",
        action="append",
        default=[],
        metavar="PROC@SECONDS",
        help="the same as --fault 'kill PROC@SECONDS': SIGKILL agent-N or the logger at that "
        "simulated time (repeatable)",
    )
    run.add_argument(
        "--timeout",
        type=seconds(),
        default=None,
        metavar="SECONDS",
        help="stop the run after this much wall-clock time in s, with exit code 124 (default: no limit)",
    )
    run.add_argument(
        "--no-logger",
        action="store_true",
        help="no logger process: no recording.rrd (so nothing for swarm report to draw), a little faster",
    )
    run.add_argument(
        "--live",
        metavar="URL",
        type=rerun_url,
        help="also stream to a Rerun viewer already listening there, e.g. "
        "rerun+http://127.0.0.1:9876/proxy (start one with: rerun); if none answers, "
        "the run goes on without it",
    )
    run.add_argument(
        "--serve-web",
        action="store_true",
        help="also serve the Rerun web viewer while the run lasts; prints the address that "
        "opens it on the run (best with --mode realtime)",
    )
    run.add_argument(
        "--grpc-port",
        type=port,
        default=None,
        metavar="PORT",
        help=f"with --serve-web: the port the logger serves the data on (default: {GRPC_PORT})",
    )
    run.add_argument(
        "--web-port",
        type=port,
        default=None,
        metavar="PORT",
        help=f"with --serve-web: the port of the viewer's page, http://127.0.0.1:PORT (default: {WEB_PORT})",
    )
    group = run.add_argument_group("agents on other machines (deploy/README.md)")
    group.add_argument(
        "--hosts",
        default=None,
        metavar="NAME[,NAME...]",
        help="run the agents on these machines, each serving with swarm host --name NAME; the "
        "world and the logger stay here (default: everything here)",
    )
    group.add_argument(
        "--place",
        default=None,
        metavar="ROBOT=HOST[,...]",
        help="with --hosts: put these robots on these hosts, e.g. 1=a,2=b; the others go "
        "round-robin over the hosts (default: all round-robin)",
    )
    group.add_argument(
        "--listen",
        default=None,
        metavar="ENDPOINT",
        help="with --hosts: where the world listens for the hosts' agents, an address they reach, "
        "e.g. tcp/192.168.1.10:7447",
    )
    group.add_argument(
        "--host-logins",
        default=None,
        metavar="FILE",
        help="with --hosts: the hosts' logins, hosts.txt of swarm secure --hosts; the run's router lets them in",
    )
    group.add_argument(
        "--hosts-timeout",
        type=seconds(),
        default=30.0,
        metavar="SECONDS",
        help="with --hosts: how long to wait for every host to connect (default: 30)",
    )
    add_tls_arguments(group)
    run.set_defaults(func=_cmd_run, parser=run)


def _add_sim(sub: argparse._SubParsersAction[Parser]) -> None:
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


def build_parser() -> Parser:
    parser = Parser(prog="swarm", description=__doc__)
    parser.add_argument(
        "--version", action="version", version=f"formation-swarm {__version__}", help="print the version and exit"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", title="commands")
    scenarios = sub.add_parser(
        "scenarios",
        help="list the shipped scenarios, each with its description",
        description="List the scenarios installed with the package, by the name that "
        "swarm run takes, each with the first comment line of its file.",
    )
    scenarios.set_defaults(func=_cmd_scenarios, parser=scenarios)
    _add_run(sub)
    for name in ("report", "export", "compare", "sweep", "results"):
        sub.add_parser(name, help=DELEGATED[name][1], add_help=False)
    _add_sim(sub)
    for name in ("world", "agent", "logger", "router", "secure", "host", "doctor"):
        sub.add_parser(name, help=DELEGATED[name][1], add_help=False)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in DELEGATED:
        import importlib

        return int(importlib.import_module(DELEGATED[argv[0]][0]).main(argv[1:]))
    parser = build_parser()
    if not argv:
        parser.print_help()
        return USAGE_ERROR
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # said by the command's parser, which knows its flags, rather than by swarm's
        args.parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    from formation_swarm.runtime.proc import OutlivesItsReader

    # A reader that leaves early (swarm run ... | head) must not cut a run short.
    stdout, sys.stdout = sys.stdout, OutlivesItsReader(sys.stdout)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        sys.stdout = stdout


if __name__ == "__main__":
    sys.exit(main())
