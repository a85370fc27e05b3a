"""ROS 2 messages: type hashes against rosbags and published values, CDR round trips, refusals."""

from __future__ import annotations

import math

import pytest
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.msg import get_types_from_msg

from formation_swarm.ros2 import messages, topics

TWIST_HASH = "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"
# std_msgs/String's, as rmw_zenoh's docs/design.md prints it in its key examples.
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
CDR = b"\x00\x01\x00\x00"
TYPES = [topics.CLOCK, topics.TF, topics.ODOM, topics.CAMERA, topics.FORMATION, topics.ERROR, topics.TWIST]


def test_twist_and_string_hashes_equal_the_published_values() -> None:
    assert messages.type_hash("geometry_msgs/msg/Twist") == TWIST_HASH
    assert messages.type_hash("std_msgs/msg/String") == STRING_HASH


@pytest.mark.parametrize("msgtype", TYPES)
def test_hash_equals_rosbags_from_the_definition_text(msgtype: str) -> None:
    # A store of no types, given the definitions as text (as a .msg file holds
    # them), hashes each type the same as the distro's store.
    store = get_typestore(Stores.EMPTY)
    text = messages.msgdef(msgtype)
    blocks = text.split("=" * 80 + "\n")
    found = get_types_from_msg(blocks[0], msgtype)
    for block in blocks[1:]:
        head, _, body = block.partition("\n")
        pkg, name = head.removeprefix("MSG: ").split("/")
        found.update(get_types_from_msg(body, f"{pkg}/msg/{name}"))
    store.register(found)
    assert store.hash_rihs01(msgtype) == messages.type_hash(msgtype)
    assert messages.type_hash(msgtype)[:7] == "RIHS01_"
    assert len(messages.type_hash(msgtype)) == 71


def test_dds_type_name() -> None:
    assert messages.dds_type_name("geometry_msgs/msg/Twist") == "geometry_msgs::msg::dds_::Twist_"
    with pytest.raises(ValueError, match="package/msg/Name"):
        messages.dds_type_name("geometry_msgs/Twist")


def test_unknown_distro_and_type_are_refused() -> None:
    with pytest.raises(ValueError, match="distro must be one of jazzy, kilted"):
        messages.typestore("humble")
    with pytest.raises(ValueError, match="is not a message of ROS 2 jazzy"):
        messages.type_hash("nope_msgs/msg/Nope")


def test_build_sets_given_fields_and_zeroes_the_rest() -> None:
    msg = messages.build("geometry_msgs/msg/Twist", linear={"x": 0.5}, angular={"z": -0.25})
    assert (msg.linear.x, msg.linear.y, msg.angular.z) == (0.5, 0.0, -0.25)
    with pytest.raises(ValueError, match="no field 'speed'"):
        messages.build("geometry_msgs/msg/Twist", speed=1.0)


def test_cdr_has_the_little_endian_header_and_round_trips() -> None:
    state = topics.TickState(
        time_s=12.35,
        robots=(
            topics.RobotTick(robot=1, x_m=1.0, y_m=-2.0, theta_rad=2.5, v_mps=1.5, sightings=((2, 1.5, 0.1, -0.2),)),
            topics.RobotTick(robot=2, x_m=0.5, y_m=-3.0, theta_rad=-1.0, formation_error_m=0.25),
        ),
        formation=1,
    )
    for _, msgtype, msg in topics.tick_messages(state):
        data = messages.encode(msgtype, msg)
        assert data[:4] == messages.CDR_LE
        assert messages.encode(msgtype, messages.decode(msgtype, data)) == data
    twist = messages.encode(topics.TWIST, messages.build(topics.TWIST, linear={"x": 1.0}))
    assert len(twist) == 4 + 6 * 8


@pytest.mark.parametrize(
    "data",
    [b"", b"\x00\x01\x00", b"\x00\x01\x00\x00" + bytes(20), b"\x01\x00\x00\x00" + bytes(48), CDR + bytes(60)],
    ids=["empty", "short-header", "short-body", "big-endian-header", "trailing-bytes"],
)
def test_malformed_cdr_is_a_value_error(data: bytes) -> None:
    with pytest.raises(ValueError, match="geometry_msgs/msg/Twist"):
        messages.decode(topics.TWIST, data)


def test_stamp_and_yaw() -> None:
    assert messages.stamp(12.35) == {"sec": 12, "nanosec": 350_000_000}
    with pytest.raises(ValueError, match="time_s must be finite"):
        messages.stamp(math.nan)
    q = messages.build("geometry_msgs/msg/Quaternion", **messages.yaw_quaternion(-2.0))
    assert messages.quaternion_yaw(q) == pytest.approx(-2.0, abs=1e-12)
