"""The swarm's ROS 2 topics, built from one tick's plain numbers: the one
function the live bridge and ``swarm export --mcap`` share.

    TickState(time_s, robots=(RobotTick, ...), formation=code | None)
    RobotTick(robot, x_m, y_m, theta_rad, v_mps, omega_rps, sightings, formation_error_m)
    tick_messages(state, namespace="", distro="jazzy") -> [(topic, msgtype, msg), ...]
    twist_to_wheels(linear_x_mps, angular_z_rps, width_m, max_wheel_mps=None) -> (left, right)
    wheels_to_twist(left_mps, right_mps, width_m) -> (linear_x_mps, angular_z_rps)
    motion(before, after, dt_s) -> (v_mps, omega_rps)   the twist that took a pose to the next

Topics of a tick, in this order (N: each robot; F: each follower), every
header stamped with the tick's sim time:

    /clock                    rosgraph_msgs/msg/Clock         sim time
    /tf                       tf2_msgs/msg/TFMessage          map -> robotN/base_link (200 a message)
    /robotN/odom              nav_msgs/msg/Odometry           frame map, child robotN/base_link
    /robotN/camera            visualization_msgs/msg/MarkerArray  what robot N's camera saw
    /formation                std_msgs/msg/UInt8              the formation code flown
    /robotF/formation_error   std_msgs/msg/Float64            |position - true target|, m

The world frame is ``map`` (x east, y north, yaw CCW: REP-103's axes); a
robot's ``base_link`` has x ahead and y to its left. Odometry's twist is in
``base_link``: linear.x the forward speed, angular.z the turn rate. A
camera's MarkerArray starts with a DELETEALL marker, then one arrow per
marker seen (ns ``camera``, id the seen robot's id) at the reading's range
and bearing in the observer's ``base_link``, pointing along the seen robot's
heading. ``/formation`` is the wire's one-byte code (the scenario's
[formations] in file order); a tick without one has no /formation message.
Topics are under ``namespace`` when one is given; frames are not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from formation_swarm.ros2.messages import DEFAULT_DISTRO, build, stamp, yaw_quaternion
from formation_swarm.world.kinematics import body_twist

CLOCK = "rosgraph_msgs/msg/Clock"
TF = "tf2_msgs/msg/TFMessage"
ODOM = "nav_msgs/msg/Odometry"
CAMERA = "visualization_msgs/msg/MarkerArray"
FORMATION = "std_msgs/msg/UInt8"
ERROR = "std_msgs/msg/Float64"
TWIST = "geometry_msgs/msg/Twist"
MAP = "map"
MARKER_M = (0.4, 0.15, 0.15)  # an arrow's length and width, m
# About 100 bytes a transform: a /tf message stays far below the 40 kB a router
# forwards (protocol.session.ROUTED_LIMIT_BYTES); more robots, more /tf messages.
TF_PER_MESSAGE = 200
DELETEALL = 3  # visualization_msgs/Marker.DELETEALL
ARROW = 0  # visualization_msgs/Marker.ARROW


@dataclass(frozen=True, slots=True, kw_only=True)
class RobotTick:
    """One robot at one tick: its true pose (world frame), body twist and what
    its camera saw, as Observation.readings: (robot_id, rho_m, phi_rad,
    beta_rad), beta positive to the robot's right (docs/paper.md)."""

    robot: int
    x_m: float
    y_m: float
    theta_rad: float
    v_mps: float = 0.0
    omega_rps: float = 0.0
    sightings: tuple[tuple[int, float, float, float], ...] = ()
    formation_error_m: float | None = None  # followers only


@dataclass(frozen=True, slots=True, kw_only=True)
class TickState:
    time_s: float
    robots: tuple[RobotTick, ...]
    formation: int | None = None


def base_link(robot: int) -> str:
    return f"robot{robot}/base_link"


def topic(name: str, namespace: str = "") -> str:
    """``name`` (``clock``, ``robot2/odom``) under ``namespace``, fully qualified."""
    ns = namespace.strip("/")
    return f"/{ns}/{name}" if ns else f"/{name}"


def cmd_vel(robot: int, namespace: str = "") -> str:
    """The topic a ROS node drives ``robot`` on (geometry_msgs/msg/Twist)."""
    return topic(f"robot{robot}/cmd_vel", namespace)


def tick_messages(state: TickState, namespace: str = "", distro: str = DEFAULT_DISTRO) -> list[tuple[str, str, Any]]:
    """Every message of one tick, as (fully qualified topic, msgtype, message)."""
    t = stamp(state.time_s)
    out: list[tuple[str, str, Any]] = [(topic("clock", namespace), CLOCK, build(CLOCK, distro, clock=t))]
    transforms = [
        {
            "header": {"stamp": t, "frame_id": MAP},
            "child_frame_id": base_link(r.robot),
            "transform": {"translation": {"x": r.x_m, "y": r.y_m}, "rotation": yaw_quaternion(r.theta_rad)},
        }
        for r in state.robots
    ]
    stamped = [build("geometry_msgs/msg/TransformStamped", distro, **x) for x in transforms]
    for i in range(0, max(len(stamped), 1), TF_PER_MESSAGE):
        out.append((topic("tf", namespace), TF, build(TF, distro, transforms=stamped[i : i + TF_PER_MESSAGE])))
    for r in state.robots:
        out.append((topic(f"robot{r.robot}/odom", namespace), ODOM, odometry(r, t, distro)))
        out.append((topic(f"robot{r.robot}/camera", namespace), CAMERA, camera(r, t, distro)))
    if state.formation is not None:
        out.append((topic("formation", namespace), FORMATION, build(FORMATION, distro, data=int(state.formation))))
    for r in state.robots:
        if r.formation_error_m is not None:
            name = topic(f"robot{r.robot}/formation_error", namespace)
            out.append((name, ERROR, build(ERROR, distro, data=float(r.formation_error_m))))
    return out


def odometry(r: RobotTick, t: dict[str, int], distro: str = DEFAULT_DISTRO) -> Any:
    pose = {"position": {"x": r.x_m, "y": r.y_m}, "orientation": yaw_quaternion(r.theta_rad)}
    return build(
        ODOM,
        distro,
        header={"stamp": t, "frame_id": MAP},
        child_frame_id=base_link(r.robot),
        pose={"pose": pose},
        twist={"twist": {"linear": {"x": r.v_mps}, "angular": {"z": r.omega_rps}}},
    )


def camera(r: RobotTick, t: dict[str, int], distro: str = DEFAULT_DISTRO) -> Any:
    header = {"stamp": t, "frame_id": base_link(r.robot)}
    markers = [build("visualization_msgs/msg/Marker", distro, header=header, ns="camera", action=DELETEALL)]
    for seen, rho_m, phi_rad, beta_rad in r.sightings:
        # beta is positive to the right; base_link's y is to the left.
        position = {"x": rho_m * math.cos(beta_rad), "y": -rho_m * math.sin(beta_rad)}
        markers.append(
            build(
                "visualization_msgs/msg/Marker",
                distro,
                header=header,
                ns="camera",
                id=int(seen),
                type=ARROW,
                pose={"position": position, "orientation": yaw_quaternion(phi_rad)},
                scale=dict(zip("xyz", MARKER_M, strict=True)),
                color={"r": 1.0, "g": 0.6, "b": 0.0, "a": 1.0},
            )
        )
    return build(CAMERA, distro, markers=markers)


def twist_to_wheels(
    linear_x_mps: float, angular_z_rps: float, width_m: float, max_wheel_mps: float | None = None
) -> tuple[float, float]:
    """A Twist's forward speed and turn rate as differential-drive wheel speeds
    (eq. 8-9 inverted); both scaled down together, the path's curvature kept,
    when one would pass ``max_wheel_mps``. ValueError for a non-finite input."""
    for name, value in (("linear.x", linear_x_mps), ("angular.z", angular_z_rps), ("width_m", width_m)):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"{name} must be a finite number, got {value!r}")
    if width_m <= 0:
        raise ValueError(f"width_m must be > 0, got {width_m!r}")
    half = 0.5 * angular_z_rps * width_m
    left, right = linear_x_mps - half, linear_x_mps + half
    fastest = max(abs(left), abs(right))
    if max_wheel_mps is not None and fastest > max_wheel_mps:
        scale = max_wheel_mps / fastest
        left, right = left * scale, right * scale
    return left, right


def wheels_to_twist(left_mps: float, right_mps: float, width_m: float) -> tuple[float, float]:
    """Wheel speeds as (forward speed m/s, turn rate rad/s): eq. 8-9."""
    return body_twist(left_mps, right_mps, width_m)


def motion(before: tuple[float, float, float], after: tuple[float, float, float], dt_s: float) -> tuple[float, float]:
    """The constant (forward speed m/s, turn rate rad/s) that takes pose
    ``before`` to pose ``after`` (x_m, y_m, theta_rad) in ``dt_s``: the world's
    step (an arc, world.kinematics) inverted, exact for one tick's motion."""
    turn = math.remainder(after[2] - before[2], math.tau)
    half = 0.5 * turn
    # The chord of an arc of heading change 2*half runs along the middle heading
    # and is sin(half)/half times the arc's length.
    chord = (after[0] - before[0]) * math.cos(before[2] + half) + (after[1] - before[1]) * math.sin(before[2] + half)
    arc = chord if abs(half) < 1e-9 else chord * half / math.sin(half)
    return arc / dt_s, turn / dt_s
