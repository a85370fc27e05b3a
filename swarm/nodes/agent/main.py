"""The agent process's command line: one robot's agent over Zenoh.

    swarm agent --id N --scenario S.toml --run RUN [--seed N] [--stats FILE] [--peers-timeout S]
                [--world-grace S] --connect ENDPOINT

This module is the command line. The process is nodes.agent.node (its
session, waits and loop); the robot's decisions are its role's
(agents.leader_role, agents.follower_role, built by nodes.agent.setup).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from formation_swarm.nodes.agent.node import Agent, Options
from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.protocol import acl, session
from formation_swarm.runtime import cliargs
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime import spool as spool_mod
from formation_swarm.runtime.proc import SEND_DRAIN_S, exit_after_main, wait_sent
from formation_swarm.spec.scenario import Scenario

DESCRIPTION = """\
Run one robot's agent by hand: its controller, on the run's Zenoh key
space. A follower turns the world's camera observations into wheel speeds
with the paper's EKF and fuzzy controller and obeys its leader's formation
codes; the leader flies the scenario's path and sends the codes.

It connects, as a client, to the world or to the run's router, waits for
the world (the leader also for its followers), answers every tick, and
exits when the world says the run is done or leaves.

It prints one line when its session is open, one when the run starts and
one when it ends (why, and where its stats went)."""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(
        prog="swarm agent",
        description=DESCRIPTION,
        epilog=process_mod.EXIT_CODES_HELP,
    )
    ap.add_argument("--id", type=int, required=True, metavar="N", help="the robot id, one of the scenario's robots")
    cliargs.add_run_arguments(ap, seeds="the link drops and link faults", stats="this agent's counters")
    spool_mod.add_arguments(ap)
    ap.add_argument(
        "--lockstep",
        action="store_true",
        help="the world runs in lockstep: telemetry waits for the logger, never dropped",
    )
    process_mod.add_arguments(ap, waits_for="the world (and, for the leader, its followers)")
    ap.add_argument(
        "--world-grace",
        type=process_mod.seconds,
        default=None,
        metavar="S",
        help="once the run started, how long to wait for the world's token to come back after it went (our "
        "session dropped by the router, a network cut, a router restart) before leaving (default: the peers "
        "timeout)",
    )
    session.add_arguments(ap, default_mode="client")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return serve(args, process_mod.Process(f"agent {args.id}", args.peers_timeout))


def serve(
    args: argparse.Namespace,
    role: process_mod.Process,
    share: int = 1,
    made: Callable[[Agent], None] | None = None,
    sc: Scenario | int | None = None,
) -> int:
    """One robot's agent, from its flags: its session, its run, its stats;
    the exit code. ``share``: the robots whose agents run in this process
    (nodes.agent.shared), which is told of each robot's Agent by ``made``
    and loads their scenario once (``sc``)."""
    if sc is None:
        sc = role.load(args)
    if isinstance(sc, int):
        return sc
    if args.id not in sc.robots:
        role.complain(f"--id {args.id} is not a robot of this scenario; its robots are {list(sc.robots)}")
        return process_mod.EXIT_USAGE
    sess_cm = role.connect(args, login=acl.agent_user(args.id))
    if isinstance(sess_cm, int):
        return sess_cm
    seed = sc.seed if args.seed is None else args.seed
    where = process_mod.describe_session(args)
    with sess_cm as sess:
        grace = args.peers_timeout if args.world_grace is None else args.world_grace
        opts = Options(
            run_id=args.run,
            where=where,
            world_grace_s=grace,
            stats_path=args.stats,
            lockstep=args.lockstep,
            wire_spool=args.wire_spool,
            share=share,
        )
        agent = Agent(sess, sc, role_for(sc, args.id, seed), role, opts)
        if made is not None:
            made(agent)
        waits = "the world and its followers" if agent.brain.SENDS_CODES else "the world"
        part = agent.brain.describe()
        role.say(f"{where}; run {args.run}, {part}: waiting up to {role.peers_timeout_s:g} s for {waits}")
        code = agent.run()
        if agent.killed:
            return process_mod.EXIT_KILLED  # as a process of its own: no last words, no last stats
        # Our last telemetry and its end-of-stream mark may still be in our kernel
        # (the router reads them only as fast as the logger takes them): leaving
        # now could throw them away (swarm.proc.wait_sent).
        if (unsent := wait_sent(SEND_DRAIN_S)) > 0:
            role.say(f"{unsent} bytes not yet taken by the router after {SEND_DRAIN_S:g} s; leaving anyway")
        agent.stats_file.close(agent.stats())
        if code != process_mod.EXIT_NO_PEERS:
            written = f"stats in {args.stats}" if args.stats else "no --stats: counters not written"
            role.say(
                f"run {args.run} ended ({agent.end_note}), exit code {code}, "
                f"{agent.brain.answered} observations answered; {written}"
            )
    return code


if __name__ == "__main__":
    exit_after_main(main())
