"""Robot 3 of a swarm run driven from ROS 2: an rclpy node that holds robot
3's place in fig11's formations (pursuit.py).

    export RMW_IMPLEMENTATION=rmw_zenoh_cpp
    export ZENOH_SESSION_CONFIG_URI=$PWD/runs/swarm_session.json5   # session_config.py writes it
    python3 follower.py [--robot 3] [--robots 3] [--namespace NS]

It subscribes to every robot's /robotN/odom, to /formation and to /clock,
and answers each /clock with one geometry_msgs/Twist on /robot3/cmd_vel,
computed from the newest odometry, which is that of the tick before: in
lockstep the world waits for that answer. Before any odometry it answers a
Twist of zero. docs/ros2.md gives the whole recipe.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import rclpy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from rosgraph_msgs.msg import Clock
from std_msgs.msg import UInt8

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pursuit import Pose, answer  # noqa: E402 -- beside this file, found through the line above


def pose_of(msg: Odometry) -> Pose:
    """The map-frame pose (x, y, yaw) an Odometry carries."""
    q = msg.pose.pose.orientation
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    return Pose(msg.pose.pose.position.x, msg.pose.pose.position.y, yaw)


class Follower(Node):
    def __init__(self, robot: int, robots: int, namespace: str) -> None:
        super().__init__("swarm_follower")
        ns = "/" + namespace.strip("/") if namespace.strip("/") else ""
        self.robot = robot
        self.odom: dict[int, Odometry] = {}
        self.formation = 0
        for r in range(1, robots + 1):
            self.create_subscription(Odometry, f"{ns}/robot{r}/odom", lambda m, r=r: self.odom.__setitem__(r, m), 10)
        self.create_subscription(UInt8, f"{ns}/formation", self.on_formation, 10)
        self.create_subscription(Clock, f"{ns}/clock", self.on_clock, 10)
        self.cmd = self.create_publisher(Twist, f"{ns}/robot{robot}/cmd_vel", 10)

    def on_formation(self, msg: UInt8) -> None:
        self.formation = msg.data

    def on_clock(self, _clock: Clock) -> None:
        poses = {r: pose_of(m) for r, m in self.odom.items()}
        twists = {r: (m.twist.twist.linear.x, m.twist.twist.angular.z) for r, m in self.odom.items()}
        twist = Twist()
        twist.linear.x, twist.angular.z = answer(poses, twists, self.formation, self.robot)
        self.cmd.publish(twist)


def main() -> None:
    ap = argparse.ArgumentParser(description="drive one robot of a swarm run from ROS 2")
    ap.add_argument("--robot", type=int, default=3, help="the robot to drive (left to ROS by swarm run --ros2)")
    ap.add_argument("--robots", type=int, default=3, help="the run's robots (their odometry is read)")
    ap.add_argument("--namespace", default="", help="the run's [ros2] namespace, if any")
    args = ap.parse_args(remove_ros_args(sys.argv)[1:])
    rclpy.init()
    node = Follower(args.robot, args.robots, args.namespace)
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
