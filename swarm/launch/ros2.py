"""``swarm run --ros2``: the run's ROS 2 bridge, as the launcher starts it.

The scenario's ``[ros2]`` table (spec.ros2) says whether the bridge runs
(``bridge``, which ``--ros2`` sets) and its domain, namespace and distro.
The bridge (nodes.bridge) is one more process of the run, with its own
login (``ros2-bridge``); the world waits for it before tick 0. The robots
named by ``--external`` are then left to ROS, not to outside agents: the
bridge holds their agents' places and a ROS node drives each by a Twist on
``/robotN/cmd_vel``. That node's login (``ros2``: it may read every ROS
topic of the run's domain and write only those robots' ``cmd_vel``) is
``Launch.login("ros2")``; ``swarm run --ros2-login FILE`` writes it. In
lockstep with robots left to ROS, the world sends each tick's truth at
once (the bridge answers tick t once tick t - 1 is published:
nodes.bridge.role).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.protocol import acl
from formation_swarm.runtime.process import DEFAULT_PEERS_TIMEOUT_S
from formation_swarm.runtime.spool import path_for as spool_path
from formation_swarm.runtime.summary import PEERS_TIMEOUT
from formation_swarm.spec.ros2 import ros2_settings

if TYPE_CHECKING:
    from formation_swarm.launch.plan import Plan
    from formation_swarm.spec.scenario import Scenario

BRIDGE = "bridge"  # the process's name: its log, its stats


def check(sc: Scenario, external: Sequence[int]) -> tuple[bool, tuple[int, ...]]:
    """Whether the scenario runs a bridge, and the robots left to ROS (the
    external ones, then); ValueError naming the problem."""
    if not ros2_settings(sc.raw).bridge:
        return False, ()
    try:  # the ROS 2 messages come from rosbags, in the ros2 extra; a run without a bridge needs none
        import rosbags  # noqa: F401
    except ImportError:
        raise ValueError(
            "ros2: the ROS 2 bridge needs the ros2 extra (rosbags): pip install 'formation-swarm[ros2]'"
        ) from None
    if sc.leader.robot_id in external:
        raise ValueError(
            f"ros2: robot {sc.leader.robot_id} is the leader, which only its own agent flies; "
            "name followers with --external to drive them from ROS"
        )
    return True, tuple(external)


def access(plan: Plan) -> acl.RosAccess | None:
    """What the router lets the bridge and a ROS node's login do; None without a bridge."""
    if not plan.bridge:
        return None
    s = ros2_settings(plan.sc.raw)
    return acl.RosAccess(domain_id=s.domain_id, namespace=s.namespace, robots=plan.ros2_robots, login=True)


def bridge_argv(plan: Plan, endpoint: str, auth: list[str]) -> list[str]:
    """The bridge's command line (``auth``: its --auth flags, none without logins)."""
    run_dir = plan.run_dir
    wait = plan.options.peers_timeout_s
    return [
        plan.options.python,
        "-m",
        "formation_swarm.nodes.bridge.main",
        "--scenario",
        str(run_dir / "scenario.toml"),
        "--run",
        plan.run_id,
        *(["--peers-timeout", f"{wait:g}"] if wait is not None else []),
        "--stats",
        str(run_dir / "stats" / f"{BRIDGE}.json"),
        *[arg for r in plan.ros2_robots for arg in ("--robot", str(r))],
        *(["--lockstep"] if plan.options.mode == "lockstep" else []),
        *(["--wire-spool", str(spool_path(run_dir, BRIDGE))] if plan.options.record_wire else []),
        "--connect",
        endpoint,
        *auth,
    ]


def write_login(settings: Mapping[str, Any], target: str | Path) -> Path:
    """A ROS node's login (``Launch.login("ros2")``) written to ``target``
    (0600; an existing file is replaced: an earlier run's login, dead with it)."""
    path = Path(target)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(json.dumps(dict(settings), indent=1))
    os.chmod(path, 0o600)
    return path


def hand_over(say: Callable[[str], None], plan: Plan, endpoint: str) -> None:
    """The console lines that name the bridge, its topics and the robots left to ROS."""
    if not plan.bridge:
        return
    from formation_swarm.ros2 import topics  # rosbags: checked in check()

    s = ros2_settings(plan.sc.raw)
    ns = s.namespace
    say(
        f"[swarm] ROS 2 bridge ({s.distro}, rmw_zenoh) at {endpoint}: domain {s.domain_id}, topics "
        f"{topics.topic('clock', ns)}, {topics.topic('tf', ns)}, {topics.topic('robotN/odom', ns)}, "
        f"{topics.topic('robotN/camera', ns)}, {topics.topic('formation', ns)}, "
        f"{topics.topic('robotN/formation_error', ns)}"
    )
    wait = plan.options.peers_timeout_s or DEFAULT_PEERS_TIMEOUT_S
    for r in plan.ros2_robots:
        say(
            f"[swarm] robot {r} is driven from ROS 2: the world waits up to {wait:g} s (--peers-timeout) for a "
            f"node that publishes geometry_msgs/msg/Twist on {topics.cmd_vel(r, ns)} and subscribes to "
            f"{topics.topic('clock', ns)}"
        )


def login_line(login: Path, endpoint: str) -> str:
    """The console line that names a ROS node's login and how to make its session
    configuration from it (examples/ros2_follower/session_config.py), beside
    the login: it holds the same password, kept out of the current folder."""
    session = login.with_name("swarm_session.json5")
    return (
        f"[swarm] ROS 2 node's login: {login}; its Zenoh session (ZENOH_SESSION_CONFIG_URI): python3 "
        f"examples/ros2_follower/session_config.py {login} {endpoint} {session} (docs/ros2.md)"
    )


def mark_summary(summary: dict[str, Any], parts: Mapping[str, Any], robots: Sequence[int]) -> None:
    """``ros2`` in the summary: the robots driven from ROS and, per robot, the
    Twists taken and rejected (the bridge's stats); a follower's entry says
    ``"ros2": true``."""
    bridge = parts.get(BRIDGE)
    bridge = bridge if isinstance(bridge, Mapping) else {}
    summary["ros2"] = {
        "robots": list(robots),
        "ticks_published": bridge.get("ticks_published"),
        "twists": bridge.get("twists", {}),
        "rejected": bridge.get("rejected", {}),
    }
    followers = summary.get("followers") or {}
    for rid in robots:
        if isinstance(entry := followers.get(str(rid)), dict):
            entry["ros2"] = True
    if summary.get("end_reason") == PEERS_TIMEOUT and (said := never_came(parts, robots)):
        summary["ended"] = said


def never_came(parts: Mapping[str, Any], robots: Sequence[int]) -> str | None:
    """The ROS node the run waited for in vain before tick 0, in words: the
    robots it would have driven (the world's wait: their agents' places, which
    the bridge takes only once a ROS node is there) and what the bridge still
    missed of it; None if the world waited for none of them."""
    world = parts.get("world")
    waited = world.get("waited_for") if isinstance(world, Mapping) else None
    if not isinstance(waited, Mapping) or not isinstance(absent := waited.get("robots"), list):
        return None
    missing = [r for r in robots if r in absent]
    t = waited.get("timeout_s")
    if not missing or not isinstance(t, (int, float)):
        return None
    bridge = parts.get(BRIDGE)
    lacked = bridge.get("waited_for") if isinstance(bridge, Mapping) else None
    said = lacked.get("missing") if isinstance(lacked, Mapping) else None
    what = "; ".join(map(str, said)) if isinstance(said, list) and said else "see the bridge's log"
    who = f"robot{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))}"
    return (
        f"no ROS 2 node came for {who} (swarm run --ros2 --external): the world gave up waiting after {t:g} s "
        f"(--peers-timeout); the bridge waited for: {what}"
    )


def result_line(ros2: Mapping[str, Any]) -> str:
    """The summary's ``ros2``, for the result block: ticks published, each robot's Twists."""
    twists = ros2.get("twists") if isinstance(ros2.get("twists"), Mapping) else {}
    robots = "; ".join(
        f"robot {rid} driven from ROS: {n.get('taken', 0)} Twists taken, {n.get('rejected', 0)} rejected"
        + (f", {n['unawaited']} before their tick" if n.get("unawaited") else "")
        for rid, n in sorted(twists.items())
        if isinstance(n, Mapping)
    )
    return f"ROS 2 bridge: {ros2.get('ticks_published')} ticks published; " + (robots or "no robot driven from ROS")
