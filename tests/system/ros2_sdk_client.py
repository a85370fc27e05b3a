"""A ROS 2 node made with zenoh-ros2-sdk (from the package index; its own
keys, attachments, tokens and RIHS01 type hashes), for test_ros2_sdk.py. It
runs as a process of its own: the SDK keeps one Zenoh session per process,
configured by ZENOH_SESSION_CONFIG_URI. Message definitions come from a
local folder (MSGS), never fetched.

    python ros2_sdk_client.py HOST PORT MSGS OUT.json DEADLINE_S

It records every /robotN/odom and /clock it hears and answers each /clock
with a Twist on /robot3/cmd_vel from examples/ros2_follower/pursuit.py
(robot 3's slot in the formation /formation names); it ends when /clock has
been silent for QUIET_S after the first, or at the deadline, and writes
what it heard to OUT.json.
"""

from __future__ import annotations

import importlib.util
import json
import math
import queue
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
QUIET_S = 3.0
ROBOTS = (1, 2, 3)
# fig11_obstacles: robot 3's slot by formation code, (reference, back_m, right_m).
SLOTS = {0: (2, 0.0, 3.0), 1: (2, 1.5, 0.0)}


def _pursuit() -> Any:
    spec = importlib.util.spec_from_file_location("pursuit", ROOT / "examples" / "ros2_follower" / "pursuit.py")
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def main(host: str, port: int, msgs: str, out: str, deadline_s: float) -> int:
    from zenoh_ros2_sdk import ROS2Publisher, ROS2Subscriber, get_message_class, get_registry

    get_registry(msgs)  # first: the registry every later call uses reads this folder
    p = _pursuit()
    heard: dict[str, Any] = {"odom": {str(r): [] for r in ROBOTS}, "clock": [], "twists": 0}
    poses: dict[int, tuple[float, ...]] = {}
    code = [0]
    ticks: queue.SimpleQueue[float] = queue.SimpleQueue()
    where = {"router_ip": host, "router_port": port, "domain_id": 0}

    def odom(r: int, m: Any) -> None:
        pos, twist = m.pose.pose.position, m.twist.twist
        poses[r] = (pos.x, pos.y, _yaw(m.pose.pose.orientation), twist.linear.x, twist.angular.z)
        heard["odom"][str(r)].append([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, pos.x, pos.y])

    def clock(m: Any) -> None:
        t = m.clock.sec + 1e-9 * m.clock.nanosec
        heard["clock"].append(t)
        ticks.put(t)

    subs = [
        ROS2Subscriber(f"/robot{r}/odom", "nav_msgs/msg/Odometry", lambda m, r=r: odom(r, m), **where) for r in ROBOTS
    ]
    subs.append(ROS2Subscriber("/formation", "std_msgs/msg/UInt8", lambda m: code.__setitem__(0, int(m.data)), **where))
    pub = ROS2Publisher("/robot3/cmd_vel", "geometry_msgs/msg/Twist", **where)
    subs.append(ROS2Subscriber("/clock", "rosgraph_msgs/msg/Clock", clock, **where))  # last: the bridge waits for it
    vector = get_message_class("geometry_msgs/msg/Vector3")
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        try:
            ticks.get(timeout=QUIET_S if heard["clock"] else 1.0)
        except queue.Empty:
            if heard["clock"]:
                break
            continue
        ref, back_m, right_m = SLOTS.get(code[0], SLOTS[0])
        linear_x = angular_z = 0.0
        if 3 in poses and ref in poses:
            own, other = poses[3], poses[ref]
            slot = p.Slot(back_m=back_m, right_m=right_m)
            linear_x, angular_z = p.pursue(p.Pose(*own[:3]), p.Pose(*other[:3]), (other[3], other[4]), slot)
        pub.publish(linear=vector(x=linear_x, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=angular_z))
        heard["twists"] += 1
    heard["type_hashes"] = {"geometry_msgs/msg/Twist": pub.type_hash}
    Path(out).write_text(json.dumps(heard))
    for s in [*subs, pub]:
        s.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], float(sys.argv[5])))
