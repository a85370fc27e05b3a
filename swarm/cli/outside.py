"""``swarm run``'s flags for processes the run does not start: an outside
agent's robot (``--external``), a read-only login (``--observer-login``),
ROS 2 nodes (``--ros2``, ``--ros2-login``) and how long every role waits
for the others (``--peers-timeout``)."""

from __future__ import annotations

import argparse
from typing import Any

from formation_swarm.runtime.cliargs import integer, seconds
from formation_swarm.runtime.process import DEFAULT_PEERS_TIMEOUT_S


def add_outside_flags(run: argparse.ArgumentParser) -> None:
    group = run.add_argument_group("processes started by someone else (docs/protocol/outside-agents.md)")
    group.add_argument(
        "--external",
        action="append",
        type=integer(1, 10000),
        default=[],
        metavar="ROBOT",
        help="start every process but this robot's agent: the run waits (up to --peers-timeout) for an agent "
        "you start, with the one command line printed at the start (the run's endpoint, run id, login file "
        "and scenario file); lockstep waits for its answers as for any agent's (repeatable)",
    )
    group.add_argument(
        "--observer-login",
        metavar="FILE",
        default=None,
        help="let in a read-only login and write it to FILE (0600; replaced if there): it may subscribe to the "
        "whole run and its liveliness tokens and publish nothing, for a dashboard or a monitor of your own "
        "(give it as --auth FILE, with the endpoint printed at the start); valid while the run lasts",
    )
    group.add_argument(
        "--ros2",
        action="store_true",
        help="also start a ROS 2 bridge (the same as --set ros2.bridge=true): the run's topics on rmw_zenoh's "
        "keys (the scenario's [ros2] domain, namespace, distro), and the robots named by --external driven "
        "from ROS by a Twist on /robotN/cmd_vel (docs/ros2.md)",
    )
    group.add_argument(
        "--ros2-login",
        metavar="FILE",
        default=None,
        help="with the bridge: write a ROS node's login to FILE (0600; replaced if there): it may read every "
        "ROS topic of the run and write only the cmd_vel of the robots driven from ROS; valid while the run lasts",
    )
    group.add_argument(
        "--peers-timeout",
        type=seconds(1e6),
        default=None,
        metavar="SECONDS",
        help="how long the world waits for every agent (an external one too) before tick 0, and every "
        f"process for the others (default: {DEFAULT_PEERS_TIMEOUT_S:g})",
    )


def outside_options(args: argparse.Namespace) -> dict[str, Any]:
    """``Launch``'s keywords from these flags."""
    return {
        "external": list(args.external),
        "observer_login": args.observer_login,
        "peers_timeout_s": args.peers_timeout,
    }
