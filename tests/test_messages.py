"""Message schemas: round trips, every rejection reason, and the largest messages a scenario allows."""

from __future__ import annotations

import math

import msgpack
import pytest

from formation_swarm.protocol.codec import MAX_PAYLOAD_BYTES, VERSION, DecodeError, Rejections
from formation_swarm.protocol.keys import MAX_ROBOT_ID
from formation_swarm.protocol.messages import Command, FormationCode, Observation, Status, Telemetry, Truth
from formation_swarm.scenario_keys import MAX_OBSTACLES, MAX_ROBOTS

EXAMPLES = [
    Observation(0, 7, 3, 0.15, (1.0, -2.0, 0.5), ((1, 2.0, 0.1, -0.2),), ()),
    Observation(0, 8, 3, 0.15, (0.0, 0.0, 0.0), (), ((5.5, 0.3, 1.0),)),
    Command(2, 9, 3, 0.4, -0.1, 1, False),
    FormationCode(1, 10, 3, 2),
    Telemetry(2, 11, 3, 0.15, 1, 0, (0.1, 1.2), None, None, None, 0.2, 1.5, 0.5, 0.6, 0, True, 4, 1, 0),
    Telemetry(
        2, 12, 3, 0.15, 1, 0, (0.1, 1.2), (0.1, 1.1), (0.01, 0.0, 0.02), 1.1, 0.2, None, 0.5, 0.6, 2, False, 0, 0, 0
    ),  # fmt: skip
    Truth(0, 13, 3, 0.15, ((1, 0.0, 0.0, 1.57, True), (2, -1.5, -1.5, 1.57, False)), ((2, -1.5, -1.4),)),
    Status(0, 14, 3, 0.15, "running", 1120),
]


@pytest.mark.parametrize("msg", EXAMPLES, ids=lambda m: type(m).__name__)
def test_round_trip(msg: object) -> None:
    assert type(msg).from_bytes(msg.to_bytes()) == msg


def _raw(msg: object) -> list:
    return msgpack.unpackb(msg.to_bytes())


CMD = Command(2, 9, 3, 0.4, -0.1, 1, False)


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"\xc1", "not msgpack"),
        (msgpack.packb({"a": 1}), "wrong type"),
        (msgpack.packb([2, VERSION, 2]), "wrong type"),  # too short for a header
        (FormationCode(1, 1, 1, 0).to_bytes(), "wrong message type"),
        (msgpack.packb([2, VERSION + 1, *_raw(CMD)[2:]]), "unknown version"),
        (msgpack.packb(_raw(CMD)[:-1]), "wrong length"),  # a field missing
        (msgpack.packb([*_raw(CMD), 1]), "wrong length"),  # one too many
        (Command(2, 9, 3, math.nan, 0.0, 1, False).to_bytes(), "not finite"),
        (Command(2, 9, 3, 0.0, -math.inf, 1, False).to_bytes(), "not finite"),
        (msgpack.packb([2, VERSION, 2, 9, 3, "fast", 0.0, 1, False]), "wrong type"),
        (msgpack.packb([2, VERSION, 2, 9, 3, 0.0, 0.0, 1, 1]), "wrong type"),  # done must be a boolean
        (msgpack.packb([2, VERSION, MAX_ROBOT_ID + 1, 9, 3, 0.0, 0.0, 1, False]), "out of range"),
        (msgpack.packb([2, VERSION, 2, -1, 3, 0.0, 0.0, 1, False]), "out of range"),  # seq
        (msgpack.packb([2, VERSION, 2, 9, 3, 0.0, 0.0, 256, False]), "out of range"),  # formation code
        (b"\x00" * (MAX_PAYLOAD_BYTES + 1), "oversized"),
    ],
)
def test_each_bad_command_is_rejected_with_its_reason(payload: bytes, reason: str) -> None:
    with pytest.raises(DecodeError) as info:
        Command.from_bytes(payload)
    assert info.value.reason == reason
    rej = Rejections()
    assert rej.decode(Command, payload) is None
    assert rej.by_reason == {reason: 1}


def test_records_and_shapes_are_checked() -> None:
    obs = _raw(EXAMPLES[0])
    bad_reading = [*obs[:7], [[1, 2.0, 0.1]], []]  # a reading of 3 fields, not 4
    bad_pose = [*obs[:6], [1.0, 2.0], *obs[7:]]
    nan_reading = [*obs[:7], [[1, 2.0, math.nan, 0.0]], []]
    for payload, reason in ((bad_reading, "wrong shape"), (bad_pose, "wrong shape"), (nan_reading, "not finite")):
        with pytest.raises(DecodeError) as info:
            Observation.from_bytes(msgpack.packb(payload))
        assert info.value.reason == reason, payload
    status = _raw(EXAMPLES[-1])
    status[6] = "exploded"
    with pytest.raises(DecodeError, match="out of range"):
        Status.from_bytes(msgpack.packb(status))


def test_a_sender_other_than_the_key_says_is_rejected() -> None:
    rej = Rejections()
    assert rej.decode(Command, CMD.to_bytes(), sender=3) is None
    assert rej.decode(Command, CMD.to_bytes(), sender=2) == CMD
    assert rej.by_reason == {"sender mismatch": 1}
    # The world is the only sender of observations.
    assert rej.decode(Observation, Observation(5, 1, 1, 0.0, (0.0, 0.0, 0.0), (), ()).to_bytes()) is None
    assert rej.by_reason["out of range"] == 1


def _awkward(i: int) -> float:
    return -1234.5678901234567 - i * 1e-9  # a float64 on the wire (9 bytes), like any real pose


def test_the_largest_messages_a_scenario_allows_fit() -> None:
    """Ground truth of MAX_ROBOTS robots, a follower that sees all the others, a
    leader that senses MAX_OBSTACLES obstacles: each fits one payload."""
    ids = range(MAX_ROBOT_ID - MAX_ROBOTS + 1, MAX_ROBOT_ID + 1)  # the longest ids on the wire
    big = 2**53
    f = _awkward
    robots = tuple((r, f(r), f(r + 1), f(r + 2), True) for r in ids)
    truth = Truth(0, big, big, f(0), robots, tuple((r, f(r), f(r + 3)) for r in ids))
    readings = tuple((r, f(r), f(r + 1), f(r + 2)) for r in ids[1:])
    seen = Observation(0, big, big, f(0), (f(1), f(2), f(3)), readings, ())
    obstacles = tuple((f(i), f(i + 1), f(i + 2)) for i in range(MAX_OBSTACLES))
    sensed = Observation(0, big, big, f(0), (f(1), f(2), f(3)), (), obstacles)
    for msg in (truth, seen, sensed):
        payload = msg.to_bytes()
        assert len(payload) <= MAX_PAYLOAD_BYTES, (type(msg).__name__, len(payload))
        assert type(msg).from_bytes(payload) == msg
