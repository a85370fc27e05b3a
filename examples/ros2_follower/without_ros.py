"""Robot 3 of a swarm run driven as follower.py drives it, with no ROS
installed: rmw_zenoh's wire spoken over plain Zenoh, messages in CDR by
rosbags. It needs the project's environment (eclipse-zenoh and rosbags, the
ros2 extra), not ROS.

    python without_ros.py SESSION.json5 [--robot 3] [--robots 3] [--namespace NS] [--domain 0]
    python without_ros.py LOGIN.json ENDPOINT [...]

SESSION.json5 is what session_config.py writes (the line ``swarm run
--ros2-login`` prints); or give the login and the router's endpoint and it
makes the same configuration. As follower.py, it announces a node
(liveliness tokens, as ``ros2 node list`` would see it), subscribes to every
robot's /robotN/odom, /formation and /clock, and answers each /clock with
one geometry_msgs/Twist on /robot3/cmd_vel from pursuit.py's law. It takes
the samples on Zenoh's receiving thread, in the order the bridge sent them
(the odometry of tick t - 1 before /clock t), as rmw_zenoh does.

It ends when the run does (the bridge's node leaves: exit 0), on Ctrl-C or
SIGTERM (exit 130), when no /clock comes within --wait-s of its start or
--quiet-s of the last (exit 1), and for a bad argument or a router it cannot
reach (exit 2), each said in one line.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import queue
import signal
import struct
import sys
import time
from pathlib import Path
from typing import Any

import zenoh
from rosbags.typesys import Stores, get_typestore

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pursuit import Pose, answer  # noqa: E402 -- beside this file, found through the line above
from session_config import session_config  # noqa: E402

STORE = get_typestore(Stores.ROS2_JAZZY)  # Kilted's wire is the same
ODOM, CLOCK, UINT8, TWIST = (
    "nav_msgs/msg/Odometry",
    "rosgraph_msgs/msg/Clock",
    "std_msgs/msg/UInt8",
    "geometry_msgs/msg/Twist",
)
QOS = "::,10:,:,:,,"  # rmw_zenoh's compact form: reliable, volatile, keep last 10
NODE = "swarm_follower"  # follower.py's name
BRIDGE = "swarm_bridge"  # the run's end: its node leaves
ENDED = -1.0  # in the queue of ticks: the bridge left


def mangle(name: str) -> str:
    """A name inside a liveliness token: / as %, an empty name %."""
    return name.replace("/", "%") if name else "%"


class Node:
    """One ROS node on rmw_zenoh's wire: its session, its tokens, its publishers' attachments."""

    def __init__(self, session: zenoh.Session, domain: int, namespace: str) -> None:
        self.session, self.domain, self.ns = session, domain, namespace
        self.zid = str(session.zid())
        self.head = f"@ros2_lv/{domain}/{self.zid}/0"
        self.names = f"%/{mangle(namespace)}/{NODE}"  # enclave, namespace, node
        self.held: list[Any] = [session.liveliness().declare_token(f"{self.head}/0/NN/{self.names}")]
        self.entities, self.seq, self.gid = 0, 0, os.urandom(16)

    def _entity(self, kind: str, topic: str, msgtype: str) -> tuple[str, str]:
        """The topic's key, after the entity's token (kind MP or MS) is declared."""
        full = f"{self.ns}{topic}"
        pkg, _, name = msgtype.split("/")
        dds, rihs = f"{pkg}::msg::dds_::{name}_", STORE.hash_rihs01(msgtype)
        self.entities += 1
        token = f"{self.head}/{self.entities}/{kind}/{self.names}/{mangle(full)}/{dds}/{rihs}/{QOS}"
        self.held.append(self.session.liveliness().declare_token(token))
        return f"{self.domain}/{full.lstrip('/')}/{dds}/{rihs}", full

    def subscribe(self, topic: str, msgtype: str, take: Any) -> None:
        key, _ = self._entity("MS", topic, msgtype)

        def on(sample: zenoh.Sample) -> None:
            try:
                take(STORE.deserialize_cdr(sample.payload.to_bytes(), msgtype))
            except Exception as exc:  # noqa: BLE001 -- a bad sample is said and skipped: the run goes on
                print(f"without_ros: dropped a sample on {topic}: {exc}", file=sys.stderr, flush=True)

        # On the receiving thread, as rmw_zenoh takes samples: in the order they came, topics mixed.
        self.held.append(self.session.declare_subscriber(key, zenoh.handlers.Callback(on, indirect=False)))

    def publisher(self, topic: str, msgtype: str) -> zenoh.Publisher:
        key, _ = self._entity("MP", topic, msgtype)
        pub = self.session.declare_publisher(key)
        self.held.append(pub)
        return pub

    def put(self, pub: zenoh.Publisher, payload: bytes) -> None:
        """A sample with rmw_zenoh's attachment: sequence number, source time (ns), GID's length and GID."""
        self.seq += 1
        pub.put(payload, attachment=struct.pack("<qqB16s", self.seq, time.time_ns(), 16, self.gid))


class Driver:
    """Robot ``robot``'s Twists: the newest odometry and formation kept as they
    come; each /clock queued with what was known then, for the main thread."""

    def __init__(self, node: Node, robot: int, robots: int) -> None:
        self.node, self.robot = node, robot
        self.poses: dict[int, Pose] = {}
        self.twists: dict[int, tuple[float, float]] = {}
        self.formation = 0
        self.sent = 0  # Twists
        self.ticks: queue.SimpleQueue[tuple[float, dict[int, Pose], dict[int, tuple[float, float]], int]] = (
            queue.SimpleQueue()
        )
        for r in range(1, robots + 1):
            node.subscribe(f"/robot{r}/odom", ODOM, lambda m, r=r: self._odom(r, m))
        node.subscribe("/formation", UINT8, lambda m: setattr(self, "formation", int(m.data)))
        self.cmd = node.publisher(f"/robot{robot}/cmd_vel", TWIST)
        node.subscribe("/clock", CLOCK, self._clock)  # last: with it the bridge counts this node in
        node.session.liveliness().declare_subscriber(
            f"@ros2_lv/{node.domain}/**", zenoh.handlers.Callback(self._graph, indirect=False), history=True
        )

    def _odom(self, r: int, m: Any) -> None:
        p, q, t = m.pose.pose.position, m.pose.pose.orientation, m.twist.twist
        yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
        self.poses[r], self.twists[r] = Pose(p.x, p.y, yaw), (t.linear.x, t.angular.z)

    def _clock(self, m: Any) -> None:
        self.ticks.put((m.clock.sec + 1e-9 * m.clock.nanosec, dict(self.poses), dict(self.twists), self.formation))

    def _graph(self, sample: zenoh.Sample) -> None:
        parts = str(sample.key_expr).split("/")
        bridge = len(parts) == 9 and parts[5] == "NN" and parts[8] == BRIDGE
        if bridge and sample.kind == zenoh.SampleKind.DELETE:
            self.ticks.put((ENDED, {}, {}, 0))

    def answer(self, poses: dict[int, Pose], twists: dict[int, tuple[float, float]], formation: int) -> None:
        linear_x, angular_z = answer(poses, twists, formation, self.robot)
        vec = STORE.types["geometry_msgs/msg/Vector3"]
        msg = STORE.types[TWIST](linear=vec(x=linear_x, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=angular_z))
        self.node.put(self.cmd, bytes(STORE.serialize_cdr(msg, TWIST)))
        self.sent += 1


def drive(driver: Driver, wait_s: float, quiet_s: float) -> tuple[int, str]:
    """Answer every /clock until the run ends or a deadline passes: the exit code and why it stopped."""
    last_t = None
    while True:
        limit = wait_s if last_t is None else quiet_s
        try:
            t, poses, twists, formation = driver.ticks.get(timeout=limit)
        except queue.Empty:
            if last_t is None:
                return 1, (
                    f"no /clock within {limit:g} s (--wait-s); check that the run leaves robot {driver.robot} to "
                    f"ROS (swarm run --ros2 --external {driver.robot}) and that --domain is the scenario's "
                    "ros2.domain_id"
                )
            return 1, f"no /clock for {limit:g} s (--quiet-s) after sim t={last_t:.2f} s: the run stalls"
        if t == ENDED:
            return 0, "the run ended (its ROS 2 bridge left)"
        while not driver.ticks.empty():  # real time: a newer /clock supersedes one not yet answered
            newer = driver.ticks.get()
            if newer[0] == ENDED:
                return 0, "the run ended (its ROS 2 bridge left)"
            t, poses, twists, formation = newer
        driver.answer(poses, twists, formation)
        last_t = t


def _config(args: argparse.Namespace) -> zenoh.Config:
    """The session's configuration: the file given, or one made from the login and the endpoint."""
    if args.endpoint is None:
        if not Path(args.config).is_file():
            raise ValueError("no such file (session_config.py writes it)")
        return zenoh.Config.from_file(args.config)
    with open(args.config) as f:
        login = json.load(f)
    return zenoh.Config.from_json5(json.dumps(session_config(login, args.endpoint)))


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="e.g. python without_ros.py runs/swarm_session.json5 (docs/ros2.md gives the recipe)",
    )
    ap.add_argument("config", metavar="SESSION.json5|LOGIN.json", help="session_config.py's file, or the login")
    ap.add_argument("endpoint", nargs="?", metavar="ENDPOINT", help="with a login: the router's, tcp/HOST:PORT")
    ap.add_argument("--robot", type=int, default=3, help="the robot to drive (default 3)")
    ap.add_argument("--robots", type=int, default=3, help="the run's robots, whose odometry is read (default 3)")
    ap.add_argument("--namespace", default="", help="the scenario's ros2.namespace, if any")
    ap.add_argument(
        "--domain",
        type=int,
        default=os.environ.get("ROS_DOMAIN_ID", "0"),  # a string: argparse checks it as it would the flag's
        help="the scenario's ros2.domain_id (default $ROS_DOMAIN_ID, else 0)",
    )
    ap.add_argument("--wait-s", type=float, default=90.0, help="for the first /clock, s (default 90)")
    ap.add_argument("--quiet-s", type=float, default=10.0, help="for each later /clock, s (default 10)")
    return ap


def _words(exc: Exception) -> str:
    """An error's words on one line; Zenoh's without the Rust source line after them."""
    return " ".join(str(exc).split(" at /")[0].split())


def _interrupt(_signum: int, _frame: Any) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    ns = "/" + args.namespace.strip("/") if args.namespace.strip("/") else ""
    for signum in (signal.SIGINT, signal.SIGTERM):  # SIGINT too: a shell starts a background job ignoring it
        signal.signal(signum, _interrupt)  # the session then closes, its tokens go
    try:
        if not (args.robot >= 1 and args.robots >= 1 and 0 <= args.domain <= 232):
            raise ValueError(f"--robot {args.robot}, --robots {args.robots}, --domain {args.domain}: out of range")
        if not all(0 < s < math.inf for s in (args.wait_s, args.quiet_s)):
            raise ValueError(f"--wait-s {args.wait_s:g}, --quiet-s {args.quiet_s:g}: each must be a positive number")
        conf = _config(args)
    except (OSError, ValueError, zenoh.ZError) as exc:
        print(f"without_ros: {args.config}: {_words(exc)}", file=sys.stderr, flush=True)
        return 2
    try:
        session = zenoh.open(conf)
    except zenoh.ZError as exc:
        print(
            f"without_ros: cannot join the run's router ({args.endpoint or args.config}): {_words(exc)}",
            file=sys.stderr,
        )
        return 2
    except KeyboardInterrupt:
        print("without_ros: interrupted while connecting", file=sys.stderr, flush=True)
        return 130
    driver = None
    with session:
        try:
            driver = Driver(Node(session, args.domain, ns), args.robot, args.robots)
            print(
                f"without_ros: node {NODE} on domain {args.domain}: waiting up to {args.wait_s:g} s for {ns}/clock, "
                f"answering with Twists on {ns}/robot{args.robot}/cmd_vel",
                flush=True,
            )
            code, why = drive(driver, args.wait_s, args.quiet_s)
        except KeyboardInterrupt:
            code, why = 130, "interrupted"
    said = f"without_ros: {why}; {driver.sent if driver else 0} Twists sent for robot {args.robot}"
    print(said, file=sys.stdout if code == 0 else sys.stderr, flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
