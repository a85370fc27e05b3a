"""The ROS 2 bridge process's command line: a run's topics on rmw_zenoh's keys.

    swarm bridge --scenario S.toml --run RUN [--robot N ...] [--lockstep] [--stats FILE]
                 [--wire-spool FILE] [--peers-timeout S] --connect ENDPOINT [--auth FILE]

This module is the command line; the process is nodes.bridge.node, its
decisions nodes.bridge.role. ``swarm run --ros2`` starts it (docs/ros2.md).
"""

from __future__ import annotations

from formation_swarm.nodes.bridge.node import Bridge, Options
from formation_swarm.nodes.bridge.role import BridgeRole
from formation_swarm.protocol import acl, session
from formation_swarm.runtime import cliargs
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime import spool as spool_mod
from formation_swarm.runtime.proc import exit_after_main, write_json
from formation_swarm.spec.ros2 import ros2_settings

DESCRIPTION = """\
Bridge one run to ROS 2: publish its ground truth each tick on ROS 2's
Zenoh keys (rmw_zenoh, the scenario's [ros2] domain, namespace and distro):
/clock, /tf, /robotN/odom, /robotN/camera, /formation and each follower's
/robotN/formation_error, with the liveliness tokens that make them visible
to ros2 topic list. For each --robot, it stands in for the robot's agent:
a geometry_msgs/Twist on /robotN/cmd_vel becomes the robot's wheel speeds.

It connects as a client to the run's router with the ros2-bridge login,
waits for the world (and, for each --robot, for a ROS node that publishes
its cmd_vel and subscribes to /clock), and exits when the run is done."""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(prog="swarm bridge", description=DESCRIPTION, epilog=process_mod.EXIT_CODES_HELP)
    cliargs.add_run_arguments(ap, seeds=None, stats="the bridge's counters")
    ap.add_argument(
        "--robot",
        action="append",
        type=cliargs.integer(1, 10000),
        default=[],
        metavar="N",
        help="a follower driven from ROS by /robotN/cmd_vel: the bridge holds its agent's place (repeatable)",
    )
    ap.add_argument(
        "--lockstep",
        action="store_true",
        help="the world runs in lockstep: /clock says a tick once the one before is published, and the first "
        "Twist after it answers that tick",
    )
    spool_mod.add_arguments(ap)
    process_mod.add_arguments(ap, waits_for="the world (and a ROS node for each --robot)")
    session.add_arguments(ap, default_mode="client")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    role = process_mod.Process("bridge", args.peers_timeout)
    sc = role.load(args)
    if isinstance(sc, int):
        return sc
    try:
        brain = BridgeRole(sc, ros2_settings(sc.raw), args.robot, lockstep=args.lockstep)
    except ValueError as exc:
        role.complain(str(exc))
        return process_mod.EXIT_USAGE
    if strays := [r for r in args.robot if r not in sc.robots]:
        role.complain(f"--robot {strays[0]} is not a robot of this scenario; its robots are {list(sc.robots)}")
        return process_mod.EXIT_USAGE
    sess_cm = role.connect(args, login=acl.BRIDGE)
    if isinstance(sess_cm, int):
        return sess_cm
    where = process_mod.describe_session(args)
    spool = spool_mod.open_path(args.wire_spool, args.run, role.complain)
    opts = Options(run_id=args.run, where=where, stats_path=args.stats, lockstep=args.lockstep)
    try:
        with sess_cm as sess:
            role.say(f"{where}; run {args.run}: waiting up to {role.peers_timeout_s:g} s for the world")
            bridge = Bridge(sess, brain, role, opts, spool)
            code = bridge.run()
            stats = bridge.stats()
    finally:
        if spool is not None:  # what it buffers, whatever ended the loop
            spool.close()
    try:
        write_json(args.stats, stats)
    except OSError as exc:
        role.complain(f"cannot write {args.stats}: {exc.strerror or exc}")
        return process_mod.EXIT_FAILED
    taken = sum(t["taken"] for t in stats["twists"].values())
    role.say(
        f"run {args.run} ended ({bridge.end_note}), exit code {code}, {stats['ticks_published']} ticks published, "
        f"{taken} Twists taken; " + (f"stats in {args.stats}" if args.stats else "no --stats: counters not written")
    )
    return code


if __name__ == "__main__":
    exit_after_main(main())
