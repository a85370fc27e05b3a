"""rmw_zenoh's keys, tokens and attachments, checked against its docs/design.md
examples; a publisher heard by a subscriber on one Zenoh session; refusals counted."""

from __future__ import annotations

import math
import threading

import pytest
import zenoh

from formation_swarm.protocol.session import make_config
from formation_swarm.ros2 import messages, rmw, topics

STRING = "std_msgs/msg/String"
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"


def test_topic_keys_equal_the_design_examples() -> None:
    assert rmw.topic_key(0, "/chatter", STRING) == f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    ns = rmw.qualify("chatter", "/robot1")
    assert rmw.topic_key(0, ns, STRING) == f"0/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    assert rmw.topic_key(0, "/robot2/cmd_vel", topics.TWIST).startswith(
        "0/robot2/cmd_vel/geometry_msgs::msg::dds_::Twist_/RIHS01_9c45bf16"
    )


def test_tokens_equal_the_design_examples() -> None:
    listener = rmw.NodeInfo(domain=2, zid="aac3178e146ba6f1fc6e6a4085e77f21", name="listener")
    assert rmw.node_key(listener) == "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    assert rmw.entity_key("MS", listener, 10, "/chatter", STRING, qos=rmw.qos_key(10)) == (
        f"@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/"
        f"std_msgs::msg::dds_::String_/{STRING_HASH}/::,10:,:,:,,"
    )
    talker = rmw.NodeInfo(domain=2, zid="8b20917502ee955ac4476e0266340d5c", name="talker")
    assert rmw.entity_key("MP", talker, 10, "/chatter", STRING, qos=rmw.qos_key(7)) == (
        f"@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
        f"std_msgs::msg::dds_::String_/{STRING_HASH}/::,7:,:,:,,"
    )


def test_namespaces_and_qos_fields() -> None:
    node = rmw.NodeInfo(domain=0, zid="ab", name="bridge", node_id=3, namespace="/swarm/a")
    assert rmw.node_key(node) == "@ros2_lv/0/ab/3/3/NN/%/%swarm%a/bridge"
    assert rmw.qos_key(42) == "::,:,:,:,,"
    assert rmw.qos_key(5, best_effort=True, transient_local=True) == "2:1:,5:,:,:,,"


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: rmw.qualify("robot 2/odom"), "letters, digits"),
        (lambda: rmw.qualify("/robøt2/odom"), "letters, digits"),
        (lambda: rmw.qualify("/2robot/odom"), "start with a letter"),
        (lambda: rmw.topic_key(233, "/a", STRING), "domain must be"),
        (lambda: rmw.node_key(rmw.NodeInfo(domain=0, zid="a", name="a/b")), "node name"),
        (lambda: rmw.entity_key("SS", rmw.NodeInfo(domain=0, zid="a", name="n"), 1, "/a", STRING), "kind must be"),
    ],
)
def test_bad_names_are_refused(call, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        call()


def test_attachment_is_33_bytes_and_parses_back() -> None:
    gid = bytes(range(16))
    data = rmw.attachment(7, 1_700_000_000_123_456_789, gid)
    assert len(data) == 33
    assert (data[:8], data[8:16], data[16], data[17:]) == (
        (7).to_bytes(8, "little"),
        (1_700_000_000_123_456_789).to_bytes(8, "little"),
        16,
        gid,
    )
    assert rmw.parse_attachment(data) == rmw.Attachment(7, 1_700_000_000_123_456_789, gid)
    with pytest.raises(ValueError, match="33 bytes, got 32"):
        rmw.parse_attachment(data[:32])
    with pytest.raises(ValueError, match="GID length byte must be 16, got 15"):
        rmw.parse_attachment(data[:16] + b"\x0f" + gid)


def _twist(x: float) -> object:
    return messages.build(topics.TWIST, linear={"x": x}, angular={"z": 0.5})


def test_subscriber_counts_and_drops_what_does_not_decode_or_is_not_finite() -> None:
    got: list[float] = []
    sub = rmw.Intake(topics.TWIST, lambda m, a: got.append(m.linear.x))
    good = messages.encode(topics.TWIST, _twist(1.0))
    assert sub.take(good, rmw.attachment(1, 5, bytes(16)))
    assert not sub.take(good[:20], None)
    assert not sub.take(messages.encode(topics.TWIST, _twist(math.nan)), None)
    assert not sub.take(messages.encode(topics.TWIST, _twist(math.inf)), None)
    assert not sub.take(good, b"\x00" * 5)  # an attachment that is not rmw_zenoh's
    assert (sub.received, sub.rejected, got) == (5, 4, [1.0])


def test_publisher_heard_by_subscriber_with_tokens_on_one_session() -> None:
    heard: list[tuple[float, rmw.Attachment | None]] = []
    done = threading.Event()

    def on(msg: object, meta: rmw.Attachment | None) -> None:
        heard.append((msg.linear.x, meta))  # type: ignore[attr-defined]
        if len(heard) == 3:
            done.set()

    with zenoh.open(make_config("peer")) as session:
        node = rmw.Node(session, "test_node", namespace="/ns")
        sub = rmw.Subscriber(node, "robot3/cmd_vel", topics.TWIST, on)
        pub = rmw.Publisher(node, "/ns/robot3/cmd_vel", topics.TWIST)
        keys = {str(r.ok.key_expr) for r in session.liveliness().get("@ros2_lv/0/**", timeout=2.0) if r.ok}
        assert {node.key, sub.token_key, pub.token_key} <= keys, keys
        pub.put(_twist(1.0), stamp_ns=11)
        pub.put_bytes(b"\x00\x01\x00\x00junk", stamp_ns=12)
        pub.put(_twist(2.0), stamp_ns=13)
        pub.put(_twist(3.0), stamp_ns=14)
        assert done.wait(5.0), heard
        for closing in (pub, sub, node):
            closing.close()
    assert [x for x, _ in heard] == [1.0, 2.0, 3.0]
    assert [(m.seq, m.stamp_ns, m.gid) for _, m in heard] == [(n, n + 10, pub.gid) for n in (1, 3, 4)]
    assert (sub.received, sub.rejected) == (4, 1)
    assert sub.key == pub.key == rmw.topic_key(0, "/ns/robot3/cmd_vel", topics.TWIST)
