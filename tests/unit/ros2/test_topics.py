"""One tick's ROS 2 topics: which messages, and the numbers they carry."""

from __future__ import annotations

import math

import pytest

from formation_swarm.ros2 import messages, topics
from formation_swarm.world.kinematics import Pose, body_twist, from_body_frame, step

STATE = topics.TickState(
    time_s=3.05,
    robots=(
        topics.RobotTick(robot=1, x_m=1.0, y_m=2.0, theta_rad=1.2, v_mps=1.5, omega_rps=0.25),
        topics.RobotTick(
            robot=2, x_m=0.0, y_m=0.5, theta_rad=1.0, sightings=((1, 2.1, 0.2, -0.3),), formation_error_m=0.4
        ),
        topics.RobotTick(robot=3, x_m=-1.0, y_m=0.0, theta_rad=0.9, formation_error_m=0.6),
    ),
    formation=2,
)


def test_a_tick_has_each_topic_once_per_tick_or_robot() -> None:
    names = [(name, msgtype) for name, msgtype, _ in topics.tick_messages(STATE)]
    assert names == [
        ("/clock", topics.CLOCK),
        ("/tf", topics.TF),
        ("/robot1/odom", topics.ODOM),
        ("/robot1/camera", topics.CAMERA),
        ("/robot2/odom", topics.ODOM),
        ("/robot2/camera", topics.CAMERA),
        ("/robot3/odom", topics.ODOM),
        ("/robot3/camera", topics.CAMERA),
        ("/formation", topics.FORMATION),
        ("/robot2/formation_error", topics.ERROR),
        ("/robot3/formation_error", topics.ERROR),
    ]
    assert topics.tick_messages(STATE, namespace="/swarm/")[4][0] == "/swarm/robot2/odom"


def test_the_messages_carry_the_tick() -> None:
    by_topic = {name: msg for name, _, msg in topics.tick_messages(STATE)}
    assert (by_topic["/clock"].clock.sec, by_topic["/clock"].clock.nanosec) == (3, 50_000_000)
    tf = by_topic["/tf"].transforms
    assert [(t.header.frame_id, t.child_frame_id) for t in tf] == [("map", f"robot{n}/base_link") for n in (1, 2, 3)]
    assert (tf[2].transform.translation.x, tf[2].transform.translation.y) == (-1.0, 0.0)
    odom = by_topic["/robot1/odom"]
    pose = odom.pose.pose
    assert (odom.header.frame_id, odom.child_frame_id) == ("map", "robot1/base_link")
    assert (pose.position.x, pose.position.y, messages.quaternion_yaw(pose.orientation)) == pytest.approx((1, 2, 1.2))
    assert (odom.twist.twist.linear.x, odom.twist.twist.angular.z) == (1.5, 0.25)
    assert by_topic["/formation"].data == 2
    assert by_topic["/robot3/formation_error"].data == 0.6


def test_a_sighting_is_an_arrow_where_the_seen_robot_is() -> None:
    markers = {name: msg for name, _, msg in topics.tick_messages(STATE)}["/robot2/camera"].markers
    assert [(m.action, m.id, m.header.frame_id) for m in markers] == [
        (topics.DELETEALL, 0, "robot2/base_link"),
        (0, 1, "robot2/base_link"),
    ]
    seen = markers[1].pose
    # The reading's point in base_link (x ahead, y left) is the paper's body frame
    # (x right, y ahead) turned: the same world point.
    rho, beta = 2.1, -0.3
    world = from_body_frame((0.0, 0.5, 1.0), rho * math.sin(beta), rho * math.cos(beta))
    c, s = math.cos(1.0), math.sin(1.0)
    x, y = seen.position.x, seen.position.y
    assert (0.0 + c * x - s * y, 0.5 + s * x + c * y) == pytest.approx(world)
    assert messages.quaternion_yaw(seen.orientation) == pytest.approx(0.2)


def test_many_robots_split_tf() -> None:
    robots = tuple(topics.RobotTick(robot=n, x_m=n, y_m=0.0, theta_rad=0.0) for n in range(1, 451))
    tfs = [msg for name, _, msg in topics.tick_messages(topics.TickState(time_s=0.0, robots=robots)) if name == "/tf"]
    assert [len(m.transforms) for m in tfs] == [200, 200, 50]
    assert max(len(messages.encode(topics.TF, m)) for m in tfs) < 40 * 1024


def test_twist_and_wheels_are_inverse() -> None:
    left, right = topics.twist_to_wheels(1.0, 0.5, 0.5)
    assert (left, right) == (0.875, 1.125)
    assert topics.wheels_to_twist(left, right, 0.5) == (1.0, 0.5)


def test_the_wheel_limit_keeps_the_curvature() -> None:
    left, right = topics.twist_to_wheels(2.0, 2.0, 0.5, max_wheel_mps=1.5)
    assert (left, right) == pytest.approx((1.5 * 1.5 / 2.5, 1.5))
    v, w = topics.wheels_to_twist(left, right, 0.5)
    assert w / v == pytest.approx(1.0)


@pytest.mark.parametrize(("v", "w"), [(math.nan, 0.0), (0.0, math.inf), ("1", 0.0)])
def test_a_twist_that_is_not_finite_is_refused(v: object, w: object) -> None:
    with pytest.raises(ValueError, match="must be a finite number"):
        topics.twist_to_wheels(v, w, 0.5)  # type: ignore[arg-type]


@pytest.mark.parametrize(("left", "right"), [(1.0, 1.0), (0.5, 1.5), (1.5, -0.2), (-1.0, -1.0), (0.3, 0.3 + 1e-12)])
def test_motion_inverts_the_worlds_step(left: float, right: float) -> None:
    before = Pose(1.0, -2.0, 3.0)
    after = step(before, left, right, 0.5, 0.05)
    assert topics.motion(before, after, 0.05) == pytest.approx(body_twist(left, right, 0.5), abs=1e-9)
