"""The router's walls for swarm run --ros2: the bridge's login writes the
commands of the robots left to ROS and no other robot's key; the ROS node's
login writes only their cmd_vel."""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from formation_swarm.launch.launcher import free_port
from formation_swarm.protocol import acl, trust
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.session import make_config

pytestmark = pytest.mark.slow

ROBOTS = (1, 2, 3, 4)
ROS = acl.RosAccess(domain_id=7, namespace="", robots=(3,), login=True)
TWIST = "geometry_msgs::msg::dds_::Twist_/RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"


class Router:
    def __init__(self, tmp_path: Path) -> None:
        self.run = f"ros2-rules-{uuid.uuid4().hex[:8]}"
        self.keys = Keys(self.run)
        self.files = trust.write_run_secrets(tmp_path / "secrets", self.run, ROBOTS, leader_id=1, ros2=ROS)
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        conf = make_config("router", listen=[self.endpoint], settings=trust.read_settings(self.files["router"]))
        self.session = zenoh.open(conf)
        self.sessions = [self.session]

    def client(self, user: str) -> zenoh.Session:
        settings = trust.read_settings(self.files[user])
        conf = make_config("client", [self.endpoint], connect_timeout_s=2.0, settings=settings)
        s = zenoh.open(conf)
        self.sessions.append(s)
        return s

    def close(self) -> None:
        for s in reversed(self.sessions):
            s.close()


@pytest.fixture
def router(tmp_path: Path) -> Iterator[Router]:
    r = Router(tmp_path)
    try:
        yield r
    finally:
        r.close()


def collect(session: zenoh.Session, key: str) -> list[str]:
    """The keys of what the router hands ``session`` on ``key`` (not its own puts)."""
    got: list[str] = []
    lock = threading.Lock()

    def on(sample: zenoh.Sample) -> None:
        with lock:
            got.append(str(sample.key_expr))

    session.declare_subscriber(key, on, allowed_origin=zenoh.Locality.REMOTE)
    return got


def wait_for(cond: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


def test_the_logins_of_a_ros2_run(tmp_path: Path) -> None:
    files = trust.write_run_secrets(tmp_path / "s", "r1", ROBOTS, 1, ros2=ROS)
    assert {acl.BRIDGE, acl.ROS2} <= set(files)
    without = trust.write_run_secrets(tmp_path / "t", "r1", ROBOTS, 1, ros2=acl.RosAccess(robots=(3,)))
    assert acl.BRIDGE in without
    assert acl.ROS2 not in without


def test_the_bridge_writes_no_key_of_a_robot_not_left_to_ros(router: Router) -> None:
    k = router.keys
    run_keys = collect(router.session, f"{k.prefix}/**")
    ros_keys = collect(router.session, "7/**")
    bridge = router.client(acl.BRIDGE)
    refused = [
        *(k.cmd(r) for r in (1, 2, 4)),
        *(k.telemetry(r) for r in ROBOTS),
        *(k.obs(r) for r in ROBOTS),
        k.codes,
        k.status,
        k.truth,
        f"7/robot3/cmd_vel/{TWIST}",  # what only a ROS node says
        f"7/robot2/cmd_vel/{TWIST}",
    ]
    allowed = [k.cmd(3), "7/robot2/odom/x/y"]
    # The refused puts first; the allowed ones after them on the same link (in
    # order): once these arrived, the others would have.
    for key in [*refused, *allowed]:
        bridge.declare_publisher(key).put(b"x")
    assert wait_for(lambda: run_keys == [k.cmd(3)] and ros_keys == ["7/robot2/odom/x/y"])
    assert run_keys == [k.cmd(3)]
    assert ros_keys == ["7/robot2/odom/x/y"]


def test_the_bridge_holds_only_the_tokens_of_the_robots_left_to_ros(router: Router) -> None:
    k = router.keys
    seen: list[str] = []
    router.session.liveliness().declare_subscriber(f"{k.prefix}/alive/*/*", lambda s: seen.append(str(s.key_expr)))
    bridge = router.client(acl.BRIDGE)
    for r in (2, 1, 3):
        bridge.liveliness().declare_token(k.alive("agent", r))
    assert wait_for(lambda: k.alive("agent", 3) in seen)
    assert set(seen) == {k.alive("agent", 3)}


def test_a_ros_node_writes_only_the_cmd_vel_of_the_robots_left_to_ros(router: Router) -> None:
    k = router.keys
    run_keys = collect(router.session, f"{k.prefix}/**")
    ros_keys = collect(router.session, "7/**")
    node = router.client(acl.ROS2)
    heard = collect(node, "7/**")
    heard_run = collect(node, f"{k.prefix}/**")  # refused: a ROS node reads only ROS topics
    for key in [k.cmd(3), k.cmd(2), f"7/robot2/cmd_vel/{TWIST}", "7/robot2/odom/x/y", f"7/robot3/cmd_vel/{TWIST}"]:
        node.declare_publisher(key).put(b"x")
    assert wait_for(lambda: ros_keys == [f"7/robot3/cmd_vel/{TWIST}"])
    assert run_keys == []
    odom = router.session.declare_publisher("7/robot2/odom/x/y")
    status = router.session.declare_publisher(k.status)
    assert wait_for(lambda: odom.matching_status.matching)
    status.put(b"x")
    odom.put(b"y")
    assert wait_for(lambda: "7/robot2/odom/x/y" in heard)
    assert heard_run == []
