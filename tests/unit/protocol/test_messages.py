"""Message schemas: round trips, every rejection reason, and the largest messages a scenario allows."""

from __future__ import annotations

import math
from dataclasses import replace
from enum import IntEnum

import msgpack
import pytest

from formation_swarm.protocol.batch import pack_batch
from formation_swarm.protocol.codec import (
    BATCH_TAG,
    MAX_PAYLOAD_BYTES,
    VERSION,
    DecodeError,
    Rejections,
    int_in,
    unpack_batch,
)
from formation_swarm.protocol.keys import MAX_ROBOT_ID
from formation_swarm.protocol.messages import (
    Command,
    FaultCall,
    FormationCode,
    Observation,
    Status,
    Telemetry,
    Truth,
)
from formation_swarm.spec.keys import MAX_OBSTACLES, MAX_ROBOTS
from tests.helpers.messages import command, fault_call, observation, telemetry

EXAMPLES = [
    observation(seq=7, tick=3, time_s=0.15, pose=(1.0, -2.0, 0.5), readings=((1, 2.0, 0.1, -0.2),)),
    observation(seq=8, tick=3, time_s=0.15, obstacles=((5.5, 0.3, 1.0),)),
    command(seq=9, tick=3, left_mps=0.4, right_mps=-0.1, formation=1),
    FormationCode(sender=1, seq=10, tick=3, code=2),
    telemetry(
        seq=11,
        tick=3,
        time_s=0.15,
        measured=(0.1, 1.2),
        alpha_rad=0.2,
        vn=1.5,
        left_mps=0.5,
        right_mps=0.6,
        changing=True,
        obs_dropped=4,
        formation_dropped=1,
    ),
    telemetry(
        seq=12,
        tick=3,
        time_s=0.15,
        measured=(0.1, 1.2),
        estimate=(0.1, 1.1),
        target_cov=(0.01, 0.0, 0.02),
        rho_m=1.1,
        alpha_rad=0.2,
        left_mps=0.5,
        right_mps=0.6,
        steering_to=2,
    ),
    Truth(
        sender=0,
        seq=13,
        tick=3,
        time_s=0.15,
        robots=((1, 0.0, 0.0, 1.57, True), (2, -1.5, -1.5, 1.57, False)),
        targets=((2, -1.5, -1.4),),
    ),
    fault_call(seq=15, tick=3, time_s=0.15, action="freeze", index=1),
    Status(sender=0, seq=14, tick=3, time_s=0.15, state="running", total_ticks=1120),
]


@pytest.mark.parametrize("msg", EXAMPLES, ids=lambda m: type(m).__name__)
def test_round_trip(msg: object) -> None:
    assert type(msg).from_bytes(msg.to_bytes()) == msg


def _raw(msg: object) -> list:
    return msgpack.unpackb(msg.to_bytes())


CMD = command(seq=9, tick=3, left_mps=0.4, right_mps=-0.1, formation=1)


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"\xc1", "not msgpack"),
        (msgpack.packb({"a": 1}), "wrong type"),
        (msgpack.packb([2, VERSION, 2]), "wrong type"),  # too short for a header
        (FormationCode(sender=1, seq=1, tick=1, code=0).to_bytes(), "wrong message type"),
        (msgpack.packb([2, VERSION + 1, *_raw(CMD)[2:]]), "unknown version"),
        (msgpack.packb(_raw(CMD)[:-1]), "wrong length"),  # a field missing
        (msgpack.packb([*_raw(CMD), 1]), "wrong length"),  # one too many
        (
            replace(CMD, left_mps=math.nan, right_mps=0.0).to_bytes(),
            "not finite",
        ),
        (
            replace(CMD, left_mps=0.0, right_mps=-math.inf).to_bytes(),
            "not finite",
        ),
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
    assert rej.decode(Observation, replace(EXAMPLES[0], sender=5).to_bytes()) is None
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
    truth = Truth(
        sender=0, seq=big, tick=big, time_s=f(0), robots=robots, targets=tuple((r, f(r), f(r + 3)) for r in ids)
    )
    readings = tuple((r, f(r), f(r + 1), f(r + 2)) for r in ids[1:])
    seen = observation(seq=big, tick=big, time_s=f(0), pose=(f(1), f(2), f(3)), readings=readings)
    obstacles = tuple((f(i), f(i + 1), f(i + 2)) for i in range(MAX_OBSTACLES))
    sensed = observation(seq=big, tick=big, time_s=f(0), pose=(f(1), f(2), f(3)), obstacles=obstacles)
    for msg in (truth, seen, sensed):
        payload = msg.to_bytes()
        assert len(payload) <= MAX_PAYLOAD_BYTES, (type(msg).__name__, len(payload))
        assert type(msg).from_bytes(payload) == msg


def test_the_wire_format_is_pinned() -> None:
    """[tag, version, sender, seq, tick, fields...]: a change is a protocol change."""
    assert msgpack.unpackb(CMD.to_bytes()) == [2, 1, 2, 9, 3, 0.4, -0.1, 1, False]
    tags = {type(m).__name__: type(m).TAG for m in EXAMPLES}
    assert tags == {
        "Observation": 1,
        "Command": 2,
        "FormationCode": 3,
        "Telemetry": 4,
        "Truth": 5,
        "Status": 6,
        "FaultCall": 7,
    }
    assert VERSION == 1


@pytest.mark.parametrize("version", [0, 2])
def test_any_other_version_is_rejected(version: int) -> None:
    with pytest.raises(DecodeError, match=f"unknown version: {version}, expected 1"):
        Command.from_bytes(msgpack.packb([2, version, *_raw(CMD)[2:]]))


@pytest.mark.parametrize("tag", [1, 3])
def test_a_tag_on_either_side_is_the_wrong_type(tag: int) -> None:
    with pytest.raises(DecodeError, match=f"tag {tag}, expected 2"):
        Command.from_bytes(msgpack.packb([tag, *_raw(CMD)[1:]]))


def test_header_bounds_are_inclusive() -> None:
    from formation_swarm.protocol.messages import MAX_TICK

    for seq, tick in ((0, 0), (MAX_TICK, MAX_TICK)):
        last = replace(CMD, sender=MAX_ROBOT_ID, seq=seq, tick=tick, formation=255)
        assert Command.from_bytes(last.to_bytes()).tick == tick
        first = replace(CMD, sender=1, seq=seq, tick=tick, formation=0)
        assert Command.from_bytes(first.to_bytes()).seq == seq
    for i, bad in ((3, -1), (3, MAX_TICK + 1), (4, -1), (4, MAX_TICK + 1), (2, 0), (2, MAX_ROBOT_ID + 1)):
        raw = _raw(CMD)
        raw[i] = bad
        with pytest.raises(DecodeError, match="out of range"):
            Command.from_bytes(msgpack.packb(raw))
    for i, name in ((2, "sender"), (3, "seq"), (4, "tick")):
        raw = _raw(CMD)
        raw[i] = 2.0
        with pytest.raises(DecodeError, match=f"wrong type: {name} must be an integer"):
            Command.from_bytes(msgpack.packb(raw))
    assert Observation.from_bytes(EXAMPLES[0].to_bytes()).sender == 0  # the world is 0, and only the world
    with pytest.raises(DecodeError, match="sender=1 not in"):
        Observation.from_bytes(replace(EXAMPLES[0], sender=1).to_bytes())
    with pytest.raises(DecodeError, match="sender=0 not in"):
        FormationCode.from_bytes(FormationCode(sender=0, seq=1, tick=1, code=0).to_bytes())


def test_field_ranges_are_inclusive_and_named() -> None:
    ok = telemetry(steering_to=3)
    assert Telemetry.from_bytes(ok.to_bytes()).steering_to == 3
    raw = _raw(ok)
    for bad in (4, -1):
        raw[16] = bad
        with pytest.raises(DecodeError, match=f"steering_to={bad} not in"):
            Telemetry.from_bytes(msgpack.packb(raw))


def test_a_payload_of_exactly_the_limit_is_decoded() -> None:
    pad = MAX_PAYLOAD_BYTES - len(CMD.to_bytes())
    payload = CMD.to_bytes() + b"\x00" * pad  # the limit, then extra data: rejected for that, not for size
    with pytest.raises(DecodeError) as info:
        Command.from_bytes(payload)
    assert info.value.reason == "not msgpack"
    with pytest.raises(DecodeError, match="wrong length: Command has 7 fields, got 6"):
        Command.from_bytes(msgpack.packb(_raw(CMD)[:-1]))


def test_numbers_in_lists_may_be_integers_and_are_floats_after() -> None:
    obs = Observation.from_bytes(msgpack.packb([1, 1, 0, 1, 1, 0.0, [1, 2, 3.5], [[2, 1, 0, 0.5]], []]))
    assert obs.pose == (1.0, 2.0, 3.5)
    assert all(type(v) is float for v in obs.pose)
    assert obs.readings == ((2, 1.0, 0.0, 0.5),)
    with pytest.raises(DecodeError, match="not finite"):
        Observation.from_bytes(msgpack.packb([1, 1, 0, 1, 1, 0.0, [1.0, math.inf, 3.5], [], []]))
    with pytest.raises(DecodeError, match="wrong shape"):
        Observation.from_bytes(msgpack.packb([1, 1, 0, 1, 1, 0.0, [1.0, 2.0, 3.5], [[2, 1.0, 0.0, 0.5, 9.0]], []]))


def test_messages_carry_no_instance_dict() -> None:
    for msg in EXAMPLES:  # slots: small, and no stray attribute
        assert not hasattr(msg, "__dict__"), type(msg).__name__


def test_messages_are_built_by_keyword_and_keep_their_wire_order() -> None:
    with pytest.raises(TypeError):
        Command(2, 9, 3, 0.4, -0.1, 1, False)  # type: ignore[misc]  # a swapped pair would pass silently
    assert _raw(CMD) == [2, VERSION, 2, 9, 3, 0.4, -0.1, 1, False]  # header, then the fields as declared


def test_a_subclass_is_decoded_as_itself() -> None:
    assert type(Command.from_bytes(CMD.to_bytes())) is Command  # the parent's builder made first

    class Sub(Command):
        __slots__ = ()

    got = Sub.from_bytes(CMD.to_bytes())
    assert type(got) is Sub
    assert _raw(got) == _raw(CMD)


def test_a_list_of_only_non_finite_numbers_is_rejected() -> None:
    with pytest.raises(DecodeError, match="not finite"):
        Observation.from_bytes(msgpack.packb([1, 1, 0, 1, 1, 0.0, [math.inf, math.nan, math.inf], [], []]))
    obs = Observation.from_bytes(msgpack.packb([1, 1, 0, 1, 1, 0.0, [1, 2, 3], [], []]))
    assert all(type(v) is float for v in obs.pose)


def test_the_payload_limit_and_who_sends_telemetry() -> None:
    assert MAX_PAYLOAD_BYTES == 32 * 1024  # under the routed size filter of protocol.session (~40 KiB)
    tel = telemetry(sender=1, reference=2)
    assert Telemetry.from_bytes(tel.to_bytes()).sender == 1  # robot 1 may follow (when another robot leads)
    with pytest.raises(DecodeError, match="sender=0 not in"):  # the world flies no robot
        Telemetry.from_bytes(replace(tel, sender=0).to_bytes())


@pytest.mark.parametrize(
    ("msg", "at", "value", "reason"),
    [
        (CMD, 0, 2.0, "wrong message type"),
        (EXAMPLES[0], 0, True, "wrong message type"),
        (CMD, 1, 1.0, "unknown version"),
        (CMD, 1, True, "unknown version"),
    ],
)
def test_the_tag_and_the_version_are_integers(msg: object, at: int, value: object, reason: str) -> None:
    """2.0 == 2 and True == 1 in Python: the header must not take them for its tag or version."""
    raw = _raw(msg)
    assert raw[at] == value
    raw[at] = value
    with pytest.raises(DecodeError) as info:
        type(msg).from_bytes(msgpack.packb(raw))
    assert info.value.reason == reason


@pytest.mark.parametrize(
    ("at", "value", "reason"),
    [(0, 100.0, "wrong message type"), (1, 1.0, "unknown version"), (1, True, "unknown version")],
)
def test_a_batch_s_tag_and_version_are_integers(at: int, value: object, reason: str) -> None:
    batch = [BATCH_TAG, VERSION, [CMD.to_bytes()]]
    batch[at] = value
    with pytest.raises(DecodeError) as info:
        unpack_batch(msgpack.packb(batch, use_bin_type=True))
    assert info.value.reason == reason


@pytest.mark.parametrize("version", [0, 2])
def test_a_batch_of_any_other_version_is_rejected(version: int) -> None:
    with pytest.raises(DecodeError, match=f"unknown version: {version}, expected 1"):
        unpack_batch(msgpack.packb([BATCH_TAG, version, []]))
    assert unpack_batch(msgpack.packb([BATCH_TAG, 1, []])) == []


def _batch_of_size(n_bytes: int) -> bytes:
    """A batch of one bin item, exactly ``n_bytes`` long."""
    item = b"\x00" * (n_bytes - 7)  # [100, 1, [bin 16]]: 3 bytes, a 1-byte array, 3 bytes of bin header
    payload = pack_batch([item])
    assert len(payload) == n_bytes
    return payload


def test_a_batch_of_exactly_the_payload_limit_is_taken_apart() -> None:
    assert MAX_PAYLOAD_BYTES == 32768
    assert [len(b) for b in unpack_batch(_batch_of_size(32768))] == [32761]
    with pytest.raises(DecodeError, match="oversized: 32769 bytes > 32768"):
        unpack_batch(_batch_of_size(32769))


def test_a_batch_holds_at_most_256_messages() -> None:
    assert len(unpack_batch(pack_batch([b"m"] * 256))) == 256
    with pytest.raises(DecodeError) as info:
        unpack_batch(pack_batch([b"m"] * 257))
    assert info.value.reason == "not msgpack"  # refused by the unpacker, before the list is built


def _observation_with_readings(readings: list) -> bytes:
    return msgpack.packb([1, 1, 0, 1, 1, 0.0, [0.0, 0.0, 0.0], readings, []])


def test_a_record_list_holds_at_most_1024_records() -> None:
    assert len(Observation.from_bytes(_observation_with_readings([[1, 0, 0, 0]] * 1024)).readings) == 1024
    with pytest.raises(DecodeError, match=r"too many items: readings has 1025 > 1024"):
        Observation.from_bytes(_observation_with_readings([[1, 0, 0, 0]] * 1025))


def test_the_unpacker_refuses_any_array_longer_than_8192() -> None:
    """Up to 8 * MAX_ITEMS elements an array is built and refused by its check;
    one more and msgpack refuses it before building it."""
    rej = Rejections()
    for n in (8192, 8193):
        assert rej.decode(Observation, _observation_with_readings([0] * n)) is None
    assert rej.by_reason == {"too many items": 1, "not msgpack": 1}
    rej = Rejections()
    for n in (8192, 8193):  # the same anywhere in the payload, here a message that is one long array
        assert rej.decode(Observation, msgpack.packb([1, 1, 0, 1, 1, *[0] * (n - 5)])) is None
    assert rej.by_reason == {"wrong length": 1, "not msgpack": 1}


class _Side(IntEnum):
    LEFT = 1
    MIDDLE = 2
    RIGHT = 3


def test_an_int_subclass_is_taken_up_to_both_bounds() -> None:
    """Not a plain int (an IntEnum, not a bool): checked the slow way, with the same bounds."""
    check = int_in(1, 3)
    assert [check("side", s) for s in _Side] == [_Side.LEFT, _Side.MIDDLE, _Side.RIGHT]
    assert [check("side", v) for v in (1, 3)] == [1, 3]
    for v in (0, 4):
        with pytest.raises(DecodeError, match=f"out of range: side={v} not in \\[1, 3\\]"):
            check("side", v)
    with pytest.raises(DecodeError, match="wrong type: side must be an integer, got bool"):
        check("side", True)


@pytest.mark.parametrize("process", ["logger", "agent-1", f"agent-{MAX_ROBOT_ID}"])
def test_a_fault_call_hits_the_logger_or_an_agent(process: str) -> None:
    call = fault_call(process=process)
    assert FaultCall.from_bytes(call.to_bytes()).process == process


@pytest.mark.parametrize("process", ["world", "router", "zzz", "agent-0", f"agent-{MAX_ROBOT_ID + 1}", "logger2"])
def test_a_fault_call_for_any_other_process_is_refused(process: str) -> None:
    with pytest.raises(DecodeError, match="is neither logger nor agent"):
        FaultCall.from_bytes(fault_call(process=process).to_bytes())


def test_a_refused_process_name_is_quoted_to_40_characters() -> None:
    with pytest.raises(DecodeError) as info:
        FaultCall.from_bytes(fault_call(process="x" * 39 + "yz").to_bytes())
    assert str(info.value).endswith(f"process={'x' * 39 + 'y'!r} is neither logger nor agent-<robot id>")


def test_a_formation_code_is_a_byte() -> None:
    for code in (0, 255):
        assert FormationCode.from_bytes(FormationCode(sender=1, seq=1, tick=1, code=code).to_bytes()).code == code
    for code in (-1, 256):
        with pytest.raises(DecodeError, match=f"code={code} not in \\[0, 255\\]"):
            FormationCode.from_bytes(FormationCode(sender=1, seq=1, tick=1, code=code).to_bytes())


def test_a_header_without_fields_has_the_wrong_length() -> None:
    with pytest.raises(DecodeError, match="wrong length: FormationCode has 4 fields, got 3") as info:
        FormationCode.from_bytes(msgpack.packb([3, 1, 1, 1, 1]))
    assert info.value.reason == "wrong length"
    with pytest.raises(DecodeError, match="a msgpack list with a header") as info:
        FormationCode.from_bytes(msgpack.packb([3, 1, 1, 1]))
    assert info.value.reason == "wrong type"
