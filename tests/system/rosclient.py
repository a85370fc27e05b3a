"""A ROS 2 node's side of rmw_zenoh, written here from rmw_zenoh's docs/design.md
for the tests: rosbags' CDR and type hashes over plain Zenoh. It does not
import formation_swarm.ros2, so it checks the bridge independently.

    key        <domain>/<topic without leading slash>/<pkg>::msg::dds_::<Name>_/RIHS01_<hex>
    attachment int64 sequence number, int64 source timestamp (ns), byte 16, 16-byte GID
    token      @ros2_lv/<domain>/<zid>/<node id>/<entity id>/<MP|MS>/<enclave>/<namespace>
               /<node>/<topic, / as %>/<type>/<hash>/<qos>; an empty name is %
"""

from __future__ import annotations

import itertools
import math
import os
import struct
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import zenoh
from rosbags.typesys import Stores, get_typestore

from formation_swarm.protocol import trust
from formation_swarm.protocol.session import make_config

STORE = get_typestore(Stores.ROS2_JAZZY)
TWIST = "geometry_msgs/msg/Twist"
ODOM = "nav_msgs/msg/Odometry"
CLOCK = "rosgraph_msgs/msg/Clock"
TF = "tf2_msgs/msg/TFMessage"
UINT8 = "std_msgs/msg/UInt8"
MARKERS = "visualization_msgs/msg/MarkerArray"
QOS = "::,10:,:,:,,"  # reliable, volatile, keep last 10


def dds_name(msgtype: str) -> str:
    pkg, _, name = msgtype.split("/")
    return f"{pkg}::msg::dds_::{name}_"


def topic_key(domain: int, topic: str, msgtype: str) -> str:
    return f"{domain}/{topic.lstrip('/')}/{dds_name(msgtype)}/{STORE.hash_rihs01(msgtype)}"


def yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class RosNode:
    """One node, ``follower``, with its own session and its tokens."""

    def __init__(self, endpoint: str, login: Path | None, domain: int = 0) -> None:
        settings = trust.read_settings(login) if login is not None else {}
        self.session = zenoh.open(make_config("client", [endpoint], connect_timeout_s=10.0, settings=settings))
        self.domain = domain
        self.zid = str(self.session.zid())
        self.ids = itertools.count(1)
        self.seq = itertools.count(1)
        self.gid = os.urandom(16)
        node = f"@ros2_lv/{domain}/{self.zid}/0/0/NN/%/%/follower"
        self.held: list[Any] = [self.session.liveliness().declare_token(node)]

    def _token(self, kind: str, eid: int, topic: str, msgtype: str) -> str:
        head = f"@ros2_lv/{self.domain}/{self.zid}/0/{eid}/{kind}/%/%/follower"
        return f"{head}/{topic.replace('/', '%')}/{dds_name(msgtype)}/{STORE.hash_rihs01(msgtype)}/{QOS}"

    def subscribe(self, topic: str, msgtype: str, callback: Callable[[Any], None]) -> None:
        def on(sample: zenoh.Sample) -> None:
            callback(STORE.deserialize_cdr(sample.payload.to_bytes(), msgtype))

        # On the thread that received it, as rmw_zenoh takes samples: in the order they came, topics mixed.
        direct = zenoh.handlers.Callback(on, indirect=False)
        self.held.append(self.session.declare_subscriber(topic_key(self.domain, topic, msgtype), direct))
        self.held.append(self.session.liveliness().declare_token(self._token("MS", next(self.ids), topic, msgtype)))

    def publisher(self, topic: str, msgtype: str) -> zenoh.Publisher:
        pub = self.session.declare_publisher(topic_key(self.domain, topic, msgtype))
        self.held.append(pub)
        self.held.append(self.session.liveliness().declare_token(self._token("MP", next(self.ids), topic, msgtype)))
        return pub

    def put(self, pub: zenoh.Publisher, payload: bytes) -> None:
        pub.put(payload, attachment=struct.pack("<qqB16s", next(self.seq), time.time_ns(), 16, self.gid))

    def graph(self) -> list[str]:
        """Every ROS entity's token in the domain (a liveliness query)."""
        replies = self.session.liveliness().get(f"@ros2_lv/{self.domain}/**", timeout=2.0)
        return [str(r.ok.key_expr) for r in replies if r.ok is not None]

    def close(self) -> None:
        self.session.close()


def twist_bytes(linear_x: float, angular_z: float) -> bytes:
    vec = STORE.types["geometry_msgs/msg/Vector3"]
    msg = STORE.types[TWIST](linear=vec(x=linear_x, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=angular_z))
    return bytes(STORE.serialize_cdr(msg, TWIST))


class Follower:
    """Drives one robot from the topics: at each /clock, a Twist from ``law``
    (the poses of every robot by id, the formation code -> (linear_x, angular_z));
    records what it hears, per tick, and the cameras of ``cameras``."""

    def __init__(
        self,
        node: RosNode,
        robot: int,
        robots: tuple[int, ...],
        law: Callable[..., tuple[float, float]],
        cameras: tuple[int, ...] = (),
    ) -> None:
        self.node, self.robot, self.law = node, robot, law
        self.lock = threading.Lock()
        self.poses: dict[int, tuple[float, ...]] = {}  # robot -> x, y, yaw, v, w (its latest odometry)
        self.odom: dict[int, list[tuple[float, float, float, float]]] = {r: [] for r in robots}  # (t, x, y, yaw)
        self.tf: list[float] = []  # stamps
        self.clocks: list[float] = []
        self.code = 0
        self.twists = 0
        self.sent: list[tuple[float, float]] = []  # each Twist's (linear.x, angular.z), in order
        # robot -> per message: its stamp and each arrow (id, x, y, yaw) in the robot's base_link
        self.cameras: dict[int, list[tuple[float, list[tuple[int, float, float, float]]]]] = {r: [] for r in cameras}
        self.before: list[tuple[float, bytes]] = []  # (sim time, payload): sent once, before a tick's answer
        self.todo: list[tuple[float, dict[int, tuple[float, ...]], int]] = []
        self.wake = threading.Event()
        for r in robots:
            node.subscribe(f"/robot{r}/odom", ODOM, lambda m, r=r: self._odom(r, m))
        node.subscribe("/tf", TF, lambda m: self.tf.append(_t(m.transforms[0].header.stamp)))
        node.subscribe("/formation", UINT8, self._code)
        for r in cameras:
            node.subscribe(f"/robot{r}/camera", MARKERS, lambda m, r=r: self._camera(r, m))
        self.pub = node.publisher(f"/robot{robot}/cmd_vel", TWIST)
        node.subscribe("/clock", CLOCK, self._clock)  # last: the bridge waits for it
        self.done = False
        self.thread = threading.Thread(target=self._answer, daemon=True)
        self.thread.start()

    def _odom(self, r: int, m: Any) -> None:
        p = m.pose.pose
        with self.lock:
            twist = m.twist.twist
            self.poses[r] = (p.position.x, p.position.y, yaw(p.orientation), twist.linear.x, twist.angular.z)
            self.odom[r].append((_t(m.header.stamp), p.position.x, p.position.y, yaw(p.orientation)))

    def _camera(self, r: int, m: Any) -> None:
        head, *arrows = m.markers  # a DELETEALL first, then one arrow per robot seen
        seen = [(a.id, a.pose.position.x, a.pose.position.y, yaw(a.pose.orientation)) for a in arrows]
        self.cameras[r].append((_t(head.header.stamp), seen))

    def _code(self, m: Any) -> None:
        with self.lock:
            self.code = int(m.data)

    def _clock(self, m: Any) -> None:
        t = _t(m.clock)
        with self.lock:  # what is known now: the ticks before (lockstep: the bridge sends them first)
            self.clocks.append(t)
            self.todo.append((t, dict(self.poses), self.code))
        self.wake.set()

    def _answer(self) -> None:
        while not self.done:
            self.wake.wait(0.1)
            self.wake.clear()
            with self.lock:
                todo, self.todo = self.todo, []
            for t, poses, code in todo:
                for at, payload in list(self.before):
                    if t >= at:
                        self.before.remove((at, payload))
                        self.node.put(self.pub, payload)
                linear_x, angular_z = self.law(poses, code) if self.robot in poses else (0.0, 0.0)
                self.node.put(self.pub, twist_bytes(linear_x, angular_z))
                self.twists += 1
                self.sent.append((linear_x, angular_z))

    def close(self) -> None:
        self.done = True
        self.thread.join(timeout=2.0)


def _t(stamp: Any) -> float:
    return stamp.sec + stamp.nanosec * 1e-9
