"""The world process: clock, physics and sensors of one run over Zenoh.

    swarm world --scenario S.toml --run RUN [--mode lockstep|realtime] [--seed N]
                [--stats FILE] [--out DIR] [--expect-logger] [--process-faults]
                [--peers-timeout S] [zenoh flags]

By default it is also the run's Zenoh router (``--zenoh-mode router --listen ...``):
agents and the logger connect to it as clients. With ``--out`` it writes the
run's summary.json (formation_swarm.runtime.summary, as ``swarm run`` does)
from its own stats.

This module is the command line. The process is nodes.world.node (session,
liveliness, waiting for the peers), its inbox nodes.world.inbox, its two
clocks nodes.world.clock; what the world decides each tick is world.tick.

Process faults of the scenario (kill, restart, freeze) are driven from here:
at a fault's tick the world publishes a FaultCall on ``Keys.faults`` for the
launcher to execute and applies the fault's effect itself
(world.process_faults). It needs ``--process-faults``, the promise that an
executor is there: then it also waits for the executor's token before tick
0. A robot whose agent comes back (a restart, a session regained) is
re-admitted.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import time
from pathlib import Path
from typing import Any

from formation_swarm.nodes.world.node import Options, World
from formation_swarm.nodes.world.waits import waiting_for
from formation_swarm.protocol import session
from formation_swarm.runtime import cliargs, proc
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime import spool as spool_mod
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.proc import exit_after_main, write_json
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod

# The real-time world's priority in Linux's real-time class (swarm.proc.realtime_priority):
# low among real-time threads (the kernel's own run from 50 up), above every normal one.
REALTIME_PRIORITY = 10


DESCRIPTION = """\
Run the world of one run by hand: the clock, the robots' physics and their
cameras. It waits for one agent per robot of the scenario (and for the
logger, with --expect-logger), then ticks until the leader reaches its last
waypoint or the scenario's duration runs out, and tells every process of
the run that it is done.

By default it is also the run's Zenoh router: start the agents and the
logger with --connect to one of its --listen endpoints. Behind a router of
your own, give it --zenoh-mode client --connect ROUTER.

It prints one line when its session is open, one when the run starts and
one when it ends (why, and where its stats and summary went)."""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(
        prog="swarm world",
        description=DESCRIPTION,
        epilog=process_mod.EXIT_CODES_HELP,
    )
    cliargs.add_run_arguments(ap, seeds="camera noise, link drops and the faults' draws", stats="the world's metrics")
    spool_mod.add_arguments(ap)
    ap.add_argument(
        "--mode",
        choices=("lockstep", "realtime"),
        default="lockstep",
        help="lockstep: each tick waits for every agent's answer; realtime: ticks follow the wall "
        "clock, 1/dt per second (default lockstep)",
    )
    ap.add_argument(
        "--out",
        metavar="DIR",
        help="write the run's summary.json and the scenario as run (scenario.toml) into DIR, as swarm run does",
    )
    ap.add_argument("--expect-logger", action="store_true", help="also wait for the logger before the first tick")
    ap.add_argument("--expect-bridge", action="store_true", help="also wait for the ROS 2 bridge before the first tick")
    ap.add_argument(
        "--ros2-robot",
        type=cliargs.integer(1),
        action="append",
        default=[],
        metavar="N",
        help="robot N is driven from ROS 2: its commands come from the bridge, not an agent (repeatable)",
    )
    ap.add_argument(
        "--truth-every-tick",
        action="store_true",
        help="send each tick's ground truth at once, not in batches (a ROS 2 bridge in lockstep waits for it)",
    )
    ap.add_argument(
        "--rt-priority",
        type=cliargs.integer(0, 99),
        default=REALTIME_PRIORITY,
        metavar="0-99",
        help="realtime mode: run the world in Linux's real-time scheduling class at this priority, so that "
        "its ticks start on time however busy the agents keep the cores; 0 leaves it in the normal class. "
        "Without the right to (root or CAP_SYS_NICE, or an RLIMIT_RTPRIO of at least this) it stays "
        f"normal and says so (default {REALTIME_PRIORITY})",
    )
    ap.add_argument(
        "--process-faults",
        action="store_true",
        help="a process of the run (swarm run's launcher) executes the scenario's process faults (kill, restart, "
        "freeze) on the world's calls: wait for its token too before the first tick. Without it the world "
        "refuses a scenario with process faults",
    )
    process_mod.add_arguments(ap, waits_for="an agent per robot (and the logger)")
    session.add_arguments(ap, default_mode="router")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    role = process_mod.Process("world", args.peers_timeout)
    started = time.monotonic()
    sc = _scenario(args, role)
    if isinstance(sc, int):
        return sc
    # Before the session: Zenoh's threads, started with it, take the same class
    # (the commands they receive are as urgent as the ticks).
    scheduling = proc.realtime_priority(args.rt_priority) if args.mode == "realtime" else "normal"
    if scheduling.startswith("normal ("):
        role.say(f"scheduling: {scheduling}; under load its ticks may start late")
    sess_cm = role.connect(args, login="world")  # as the router its --auth holds no login: not checked
    if isinstance(sess_cm, int):
        return sess_cm
    if args.seed is not None:
        sc = sc.with_seed(args.seed)
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "scenario.toml").write_text(scenario_files.dumps(sc.raw))
    where = process_mod.describe_session(args)
    with sess_cm as sess:
        waits = waiting_for(sc.robots, args.ros2_robot, logger=args.expect_logger, bridge=args.expect_bridge)
        role.say(f"{where}; run {args.run}: waiting up to {role.peers_timeout_s:g} s for {waits}")
        opts = Options(
            run_id=args.run,
            seed=sc.seed,
            mode=args.mode,
            expect_logger=args.expect_logger,
            executor=args.process_faults,
            where=where,
            logins=args.zenoh_mode == "router" and bool(args.auth),  # it sees sessions close: nodes.world.sessions
            truth_every_tick=args.truth_every_tick,
            expect_bridge=args.expect_bridge,
            ros2_robots=tuple(args.ros2_robot),
        )
        world = World(sess, sc, role, opts)
        code = _run_spooled(args, role, world)
        if code == process_mod.EXIT_DUPLICATE:
            return code  # the run's stats and summary are the other world's: nothing written over them
        stats = world.stats(time.monotonic() - started)
        stats["exit_code"] = code
        stats["scheduling"] = scheduling
        try:
            written = _write(args, sc, world, stats)
        except OSError as exc:  # a full disk, a folder gone: one line (its log may be on that disk too)
            with contextlib.suppress(OSError):
                role.complain(f"cannot write {exc.filename or args.stats}: {exc.strerror or exc}")
            return process_mod.EXIT_FAILED
        if code == process_mod.EXIT_NO_PEERS:
            _heard_nobody(args, role, world)
            return code  # the lines that gave up were the last word
        role.say(
            f"run {args.run} ended ({_why(role, world)}), exit code {code}, {world.tick.engine.tick} ticks; {written}"
        )
    return code


def _run_spooled(args: argparse.Namespace, role: process_mod.Process, world: World) -> int:
    """The world's loop, with what it receives spooled (--wire-spool): its exit code."""
    try:
        world.spool = spool_mod.open_spool(args, role.complain)
    except OSError as exc:
        role.complain(f"cannot spool the wire to {args.wire_spool}: {exc}")
        return process_mod.EXIT_FAILED
    try:
        return world.run()
    finally:
        if world.spool is not None:  # what it buffers, whatever ended the loop (a stop signal included)
            world.spool.close()


def _heard_nobody(args: argparse.Namespace, role: process_mod.Process, world: World) -> None:
    """After the wait for peers gave up: the likely cause, when no process of the run was heard at all."""
    heard = world.peers.agents_seen or world.peers.logger_seen or world.peers.executor_seen
    if args.auth and args.zenoh_mode == "client" and not heard and not all(map(session.loopback, args.connect)):
        role.complain(
            "it heard no process of the run at all: a world's login from swarm secure is granted over "
            "the router's loopback only, so connect it to 127.0.0.1 on the router's machine (or make "
            "the logins with --world-anywhere)"
        )


def _scenario(args: argparse.Namespace, role: process_mod.Process) -> scenario_mod.Scenario | int:
    """The scenario to run, or the exit code after saying why not."""
    sc = role.load(args)
    if isinstance(sc, int):
        return sc
    if (procs := [str(f) for f in sc.faults if f.process is not None]) and not args.process_faults:
        role.complain(
            f"the scenario has process faults ({', '.join(procs)}) and nothing here executes them: swarm run "
            "does; by hand, remove them from [[faults]], or pass --process-faults with an executor of your own"
        )
        return process_mod.EXIT_USAGE
    return sc


def _why(role: process_mod.Process, world: World) -> str:
    """Why the run ended, for the last line."""
    if world.end_reason == summary_mod.INTERRUPTED:
        at = "before the run started" if world.ended_at_s is None else f"at t={world.ended_at_s:.2f} s"
        return f"{role.stopped_by()} {at}"
    return summary_mod.describe_end(world.end_reason, world.ended_at_s)


def _write(args: argparse.Namespace, sc: scenario_mod.Scenario, world: World, stats: dict[str, Any]) -> str:
    """The world's stats (--stats) and, with --out, the summary.json of a run
    whose processes were started by hand: the world's own stats (the others'
    are in their --stats files). Says what it wrote where."""
    write_json(args.stats, stats)
    written = [f"stats in {args.stats}"] if args.stats else []
    if args.out:
        code = stats["exit_code"]
        summary = summary_mod.build(
            run_id=args.run,
            sc=sc,
            mode=args.mode,
            parts={"world": stats},
            exit_code=code,
            end_reason=world.end_reason,
            ended_at_s=world.ended_at_s,
            interrupted=world.end_reason == summary_mod.INTERRUPTED,
            timed_out=False,
            processes={"world": {"pid": os.getpid(), "exit_code": code, "exit_after_stop_s": None}},
            events=[],
            recording=None,
        )
        written.append(f"summary in {summary_mod.write(Path(args.out), summary)}")
    return "; ".join(written) or "nothing written (no --stats, no --out)"


if __name__ == "__main__":
    exit_after_main(main())
