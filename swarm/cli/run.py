"""``swarm run``: its command line, checked before anything starts, and the run."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from formation_swarm.cli import interrupts
from formation_swarm.cli.outside import add_outside_flags, outside_options
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

if TYPE_CHECKING:
    from collections.abc import Callable

    from formation_swarm.launch.launcher import Launch

GRPC_PORT, WEB_PORT = 9876, 9090  # --serve-web's defaults: Rerun's own

RUN_EPILOG = """\
exit codes: 0 the run ended normally; 1 the world failed, a process failed
before tick 0 (its log's last lines are printed), a robot's controller failed,
or the run lost its leader (or every follower) for good, a kill fault included
(collisions do not fail a run: see summary.json); 2 a bad command line (one
line on stderr, nothing started); 124 --timeout; 130 interrupted (Ctrl-C).

examples:
  swarm run fig11_obstacles
  swarm run fig7_turn_vn_dynamic --seed 3 --set controller.vn=1.5 --out runs/static
  swarm run fig11_obstacles --mode realtime --serve-web     (then open the address it prints)
  swarm run fig11_obstacles --fault "kill agent-3@20s"
  swarm run fig11_obstacles --fault "restart agent-2@20s after=1s" --fault "drop obs:3@10s for=5s p=0.5"
  (every fault kind: docs/faults.md)
  swarm run fig11_obstacles --external 3        (then start robot 3's agent as the run says)
  swarm run fig11_obstacles --observer-login observer.json
  swarm run fig11_obstacles --ros2 --external 3 --ros2-login runs/ros2.json   (docs/ros2.md)
"""


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


def _launch(args: argparse.Namespace) -> Launch:
    """The run the command line asks for, checked, its folder made; ValueError
    or ScenarioError for a bad command line, with nothing made."""
    from formation_swarm.launch.launcher import KillAt, Launch
    from formation_swarm.launch.remote import parse_placement
    from formation_swarm.spec.files import parse_overrides

    kills = [KillAt.parse(spec) for spec in args.kill]
    overrides = parse_overrides(args.set)
    if args.ros2:
        overrides["ros2.bridge"] = True
    if args.agents_per_process is not None:
        overrides["run.agents_per_process"] = args.agents_per_process
    hosts = [h.strip() for h in (args.hosts or "").split(",") if h.strip()]
    launch = Launch(
        args.scenario,
        mode=args.mode,
        seed=args.seed,
        out=args.out,
        overrides=overrides,
        logger=not args.no_logger,
        record_wire=args.record_wire,
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
        **outside_options(args),
    )
    if args.out is not None and not args.out.strip():
        raise ValueError("--out '': an empty name")
    if args.out is not None and (Path(args.out) / "summary.json").exists():
        raise ValueError(f"--out {args.out}: already holds a run (summary.json); give a new folder")
    if args.ros2_login is not None and not launch.plan.bridge:
        raise ValueError("--ros2-login: only with the ROS 2 bridge (--ros2, or ros2.bridge = true)")
    if args.ros2_login is not None and Path(args.ros2_login).is_dir():
        raise ValueError(f"--ros2-login {args.ros2_login}: a folder; give a file name")
    make_folder("--out" if args.out else "run folder", launch.run_dir)  # last: nothing made for a bad input
    return launch


def _start(launch: Launch, announce: Callable[[], None]) -> int | None:
    """Start every process, saying so first; the command's exit code if the run could not start."""
    import zenoh

    from formation_swarm.launch.remote import HostError

    try:
        launch.start(announce)
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
    return None


def _cmd_run(args: argparse.Namespace) -> int:
    if conflict := _run_flag_conflicts(args):
        print(f"swarm run: {conflict} (see swarm run --help)", file=sys.stderr)
        return USAGE_ERROR
    interrupts.exit_at_once()  # nothing runs yet
    from formation_swarm.launch.console import describe_laws, print_result
    from formation_swarm.launch.sharing import per_process
    from formation_swarm.launch.words import describe_robots
    from formation_swarm.runtime.proc import interrupt_on_stop_signals
    from formation_swarm.spec.laws import laws
    from formation_swarm.spec.scenario import ScenarioError

    try:
        launch = _launch(args)
    except (ScenarioError, ValueError) as exc:
        print(f"swarm run: {exc}", file=sys.stderr)
        return USAGE_ERROR
    interrupt_on_stop_signals()  # from here Ctrl-C and SIGTERM stop the run cleanly
    robots = describe_robots(len(launch.sc.robots), per_process(launch.sc))
    line = (
        f"[swarm] run {launch.run_id}: {launch.sc.name}, {robots}, {args.mode}, "
        f"seed {launch.sc.seed}, {describe_laws(laws(launch.sc))}, folder {launch.run_dir}"
    )
    if (code := _start(launch, lambda: print(line, flush=True))) is not None:
        return code
    if args.ros2_login is not None and (settings := launch.login("ros2")) is not None:
        from formation_swarm.launch.ros2 import login_line, write_login

        print(login_line(write_login(settings, args.ros2_login), launch.endpoint), flush=True)
    with launch:
        result = launch.wait(timeout_s=args.timeout)
    if result.exit_code == interrupts.INTERRUPTED:
        return result.exit_code  # said in one line: no result block after a Ctrl-C
    if launch.interrupted:  # after the run's end was settled
        print(f"[swarm] interrupted; every process stopped; folder {launch.run_dir}", flush=True)
        return interrupts.INTERRUPTED
    print_result(result)
    return result.exit_code


def add_run(sub: argparse._SubParsersAction[Parser]) -> None:
    run = sub.add_parser(
        "run",
        help="run a scenario, every robot its own process (world, logger, agents)",
        description="Run one scenario on this machine: the world (physics, cameras, clock; also the Zenoh router), "
        "a Rerun logger and one process per robot. Progress and the metrics go to the console; the run folder gets "
        "the scenario as run, recording.rrd, summary.json and logs/.",
        epilog=RUN_EPILOG,
    )
    _add_scenario_flags(run)
    _add_fault_flags(run)
    _add_viewer_flags(run)
    add_outside_flags(run)
    _add_host_flags(run.add_argument_group("agents on other machines (deploy/README.md)"))
    run.set_defaults(func=_cmd_run, parser=run)


def _add_scenario_flags(run: argparse.ArgumentParser) -> None:
    """The scenario, how it runs, and where to."""
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
        "--agents-per-process",
        type=integer(1),
        default=None,
        metavar="K",
        help="run K robots' agents in each process, each with its own session, login and token: "
        "the same as --set run.agents_per_process=K (default: the scenario's, 1)",
    )
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one scenario key, e.g. leader.speed_mps=1.6 or controller.vn=dynamic (repeatable)",
    )


def _add_fault_flags(run: argparse.ArgumentParser) -> None:
    """The faults scheduled, and the wall-clock limit."""
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


def _add_viewer_flags(run: argparse.ArgumentParser) -> None:
    """The logger, and where it streams to."""
    run.add_argument(
        "--no-logger",
        action="store_true",
        help="no logger process: no recording.rrd (so nothing for swarm report to draw), a little faster",
    )
    run.add_argument(
        "--record-wire",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="every process spools the messages it receives and the run's end merges them into wire.mcap, "
        "for swarm replay (default: on; about 2%% of the lockstep rate: docs/replay.md)",
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


def _add_host_flags(group: argparse._ArgumentGroup) -> None:
    """Agents on other machines (deploy/README.md)."""
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
        help="with --hosts: where the launcher, the run's router, listens for the hosts, an address they reach, "
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
