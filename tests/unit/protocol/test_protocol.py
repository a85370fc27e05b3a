"""Batches of logger-bound messages: packing, timing, end of stream, bad input."""

from __future__ import annotations

import json

import msgpack
import pytest

from formation_swarm.protocol.batch import BatchPublisher, pack_batch
from formation_swarm.protocol.codec import MAX_BATCH_ITEMS, Rejections
from formation_swarm.protocol.messages import Command, FormationCode
from tests.helpers import ROOT


class FakePub:
    def __init__(self) -> None:
        self.payloads: list[bytes] = []

    def put(self, payload: bytes) -> None:
        self.payloads.append(payload)


class FakeClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def _codes(n: int, start: int = 0) -> list[bytes]:
    return [FormationCode(sender=1, seq=start + i + 1, tick=start + i, code=i % 3).to_bytes() for i in range(n)]


def test_batch_round_trip_keeps_order() -> None:
    msgs = _codes(10)
    rej = Rejections()
    out = rej.decode_batch(FormationCode, pack_batch(msgs), sender=1)
    assert [m.seq for m in out] == list(range(1, 11))
    assert rej.total == 0


def test_first_message_goes_at_once_then_one_put_per_window() -> None:
    pub, clock = FakePub(), FakeClock()
    bp = BatchPublisher(pub, window_s=0.02, clock=clock)
    msgs = _codes(30)
    bp.put(msgs[0])  # nothing sent before: leaves at once (a 20 Hz stream is never delayed)
    assert len(pub.payloads) == 1
    for i in range(1, 11):  # 10 more within 10 ms: held
        clock.t = i * 0.001
        bp.put(msgs[i])
    assert len(pub.payloads) == 1
    clock.t = 0.021
    bp.put(msgs[11])  # window passed: the 11 held leave together
    assert len(pub.payloads) == 2
    rej = Rejections()
    assert [m.seq for m in rej.decode_batch(FormationCode, pub.payloads[1])] == list(range(2, 13))


def test_close_flushes_then_marks_the_end() -> None:
    pub, clock = FakePub(), FakeClock()
    bp = BatchPublisher(pub, window_s=1.0, clock=clock)
    msgs = _codes(5)
    for m in msgs:
        bp.put(m)
    bp.close()
    rej = Rejections()
    batches = [rej.decode_batch(FormationCode, p) for p in pub.payloads]
    assert [len(b) for b in batches] == [1, 4, 0]  # first at once, the held 4, the end mark
    assert rej.total == 0


def test_full_batches_leave_early() -> None:
    pub, clock = FakePub(), FakeClock()
    bp = BatchPublisher(pub, window_s=10.0, clock=clock)
    for m in _codes(1 + 2 * MAX_BATCH_ITEMS):
        bp.put(m)
    assert [len(msgpack.unpackb(p)[2]) for p in pub.payloads] == [1, MAX_BATCH_ITEMS, MAX_BATCH_ITEMS]
    small = BatchPublisher(FakePub(), window_s=10.0, max_bytes=100, clock=clock)
    for m in _codes(40):
        small.put(m)
        assert small.size <= 100


def test_bad_batches_are_counted_once_and_bad_items_each() -> None:
    rej = Rejections()
    assert rej.decode_batch(FormationCode, b"\xc1") is None
    assert (
        rej.decode_batch(
            FormationCode,
            Command(sender=2, seq=1, tick=1, left_mps=0.0, right_mps=0.0, formation=0, done=False).to_bytes(),
        )
        is None
    )
    assert rej.decode_batch(FormationCode, msgpack.packb([100, 99, []])) is None  # unknown version
    assert rej.decode_batch(FormationCode, msgpack.packb([100, 1, [1, 2]])) is None  # items not bytes
    assert rej.decode_batch(FormationCode, b"\x00" * 70_000) is None
    assert rej.total == 5
    mixed = pack_batch(
        [
            *_codes(2),
            b"junk",
            Command(sender=2, seq=1, tick=1, left_mps=0.0, right_mps=0.0, formation=0, done=False).to_bytes(),
        ]
    )
    assert len(rej.decode_batch(FormationCode, mixed, sender=1)) == 2
    assert rej.total == 7
    assert len(rej.decode_batch(FormationCode, pack_batch(_codes(2)), sender=2)) == 0  # wrong sender
    assert rej.by_reason["sender mismatch"] == 2


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [({"window_s": -1.0}, "window_s"), ({"max_bytes": 0}, "max_bytes"), ({"max_bytes": 10**6}, "max_bytes")],
)
def test_bad_parameters_name_themselves(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        BatchPublisher(FakePub(), **kwargs)


def test_the_shipped_router_configuration_loads() -> None:

    from formation_swarm.protocol.session import ROUTED_LIMIT_BYTES, make_config

    conf = make_config("router", config_file=str(ROOT / "deploy" / "router.json5"))
    assert '"router"' in conf.get_json("mode")
    assert "tcp/0.0.0.0:7447" in conf.get_json("listen/endpoints")
    # The same transport and size filter as every process started without a file.
    ours = make_config("router", listen=["tcp/127.0.0.1:7447"])
    for key in ("transport/unicast/lowlatency", "transport/unicast/qos/enabled", "low_pass_filter"):
        assert conf.get_json(key) == ours.get_json(key), key
    assert json.loads(conf.get_json("low_pass_filter"))[0]["size_limit"] == ROUTED_LIMIT_BYTES


def test_batch_size_is_counted_again_after_each_flush() -> None:
    pub, clock = FakePub(), FakeClock()
    msgs = _codes(20)
    size = len(msgs[0])
    bp = BatchPublisher(pub, window_s=10.0, max_bytes=3 * size, clock=clock)
    for m in msgs[:7]:
        bp.put(m)
    # The first leaves at once; then three fit exactly, the fourth starts a new batch.
    assert [len(msgpack.unpackb(p)[2]) for p in pub.payloads] == [1, 3]
    assert (len(bp.items), bp.size) == (3, 3 * size)
    bp.flush()
    assert (bp.items, bp.size) == ([], 0)


def test_half_the_payload_limit_is_the_largest_batch() -> None:
    from formation_swarm.protocol.messages import MAX_PAYLOAD_BYTES

    BatchPublisher(FakePub(), max_bytes=MAX_PAYLOAD_BYTES // 2)
    with pytest.raises(ValueError, match="max_bytes"):
        BatchPublisher(FakePub(), max_bytes=MAX_PAYLOAD_BYTES // 2 + 1)


def test_a_batch_with_a_map_or_a_wrong_tag_is_refused() -> None:
    rej = Rejections()
    assert rej.decode_batch(FormationCode, msgpack.packb([99, 1, []])) is None
    assert rej.decode_batch(FormationCode, msgpack.packb([101, 1, []])) is None
    assert rej.decode_batch(FormationCode, msgpack.packb([100, 1, [{"a": 1}]])) is None
    assert rej.decode_batch(FormationCode, msgpack.packb([100, 1])) is None
    assert rej.by_reason == {"wrong message type": 2, "not msgpack": 1, "wrong type": 1}
    from formation_swarm.protocol.codec import DecodeError
    from formation_swarm.protocol.codec import unpack_batch as _unpack_batch

    with pytest.raises(DecodeError, match=r"tag 99, expected a batch \(100\)"):
        _unpack_batch(msgpack.packb([99, 1, []]))
    with pytest.raises(DecodeError, match="unknown version: 7, expected 1"):
        _unpack_batch(msgpack.packb([100, 7, []]))
    with pytest.raises(DecodeError, match="oversized"):
        _unpack_batch(b"\x00" * 70_000)


@pytest.mark.parametrize("max_bytes", [0, -1, 16385])
def test_max_bytes_out_of_its_bounds_is_refused_with_them(max_bytes: int) -> None:
    with pytest.raises(ValueError, match=rf"^max_bytes must be in \(0, 16384\], got {max_bytes}$"):
        BatchPublisher(FakePub(), max_bytes=max_bytes)


def test_max_bytes_of_1_and_a_window_of_0_are_allowed() -> None:
    pub, clock = FakePub(), FakeClock()
    bp = BatchPublisher(pub, window_s=0.0, max_bytes=1, clock=clock)
    msgs = _codes(3)
    for m in msgs:
        bp.put(m)  # no time passes: a window of 0 has passed all the same
    assert [msgpack.unpackb(p)[2] for p in pub.payloads] == [[m] for m in msgs]
    with pytest.raises(ValueError, match=r"^window_s must be >= 0, got -0.001$"):
        BatchPublisher(FakePub(), window_s=-0.001)


def test_a_put_exactly_one_window_after_the_last_sends() -> None:
    pub, clock = FakePub(), FakeClock()
    bp = BatchPublisher(pub, window_s=0.25, clock=clock)
    msgs = _codes(4)
    bp.put(msgs[0])
    clock.t = 0.125
    bp.put(msgs[1])
    clock.t = 0.2499
    bp.put(msgs[2])
    assert len(pub.payloads) == 1
    clock.t = 0.25
    bp.put(msgs[3])
    assert [len(msgpack.unpackb(p)[2]) for p in pub.payloads] == [1, 3]


def test_the_defaults_are_20_ms_and_16_kib() -> None:
    """docs/protocol.md: a window of 20 ms, and a batch of at most 16 KiB."""
    pub, clock = FakePub(), FakeClock()
    bp = BatchPublisher(pub, clock=clock)
    bp.put(b"first")
    clock.t = 0.019
    bp.put(b"second")
    assert len(pub.payloads) == 1
    clock.t = 0.02  # 20 ms after the last send
    bp.put(b"third")
    assert [msgpack.unpackb(p)[2] for p in pub.payloads] == [[b"first"], [b"second", b"third"]]
    for _ in range(4):  # no time passes: only the size sends
        bp.put(b"x" * 4096)
    assert (len(pub.payloads), bp.size) == (2, 16384)  # exactly 16 KiB held
    bp.put(b"y")
    assert [len(b) for b in msgpack.unpackb(pub.payloads[-1])[2]] == [4096] * 4
    assert bp.items == [b"y"]


def test_a_message_of_exactly_max_bytes_fits_a_batch_alone() -> None:
    pub, clock = FakePub(), FakeClock()
    m = _codes(1)[0]
    bp = BatchPublisher(pub, window_s=10.0, max_bytes=len(m), clock=clock)
    bp.put(m)  # the first leaves at once
    bp.put(m)  # held: it fills the batch
    assert (len(pub.payloads), bp.size) == (1, len(m))
    bp.put(m)  # would pass max_bytes: the held one leaves alone
    assert [len(msgpack.unpackb(p)[2]) for p in pub.payloads] == [1, 1]


def test_a_message_larger_than_max_bytes_still_leaves_at_once() -> None:
    """After a quiet window a message leaves at once, also one larger than a
    batch may be (a ground truth of 500 robots is ~27 KB): flushing an empty
    batch does not restart the window."""
    pub, clock = FakePub(), FakeClock()
    bp = BatchPublisher(pub, window_s=0.02, max_bytes=100, clock=clock)
    big = b"z" * 101
    bp.put(big)
    assert [msgpack.unpackb(p)[2] for p in pub.payloads] == [[big]]
    clock.t = 1.0
    bp.put(big)
    assert len(pub.payloads) == 2
    clock.t = 1.01
    bp.flush()  # nothing held: nothing sent, and the window still runs from the last put
    clock.t = 1.02
    bp.put(b"small")
    assert len(pub.payloads) == 3


def test_zenoh_errors_lose_their_rust_source_places() -> None:
    from formation_swarm.protocol.session import zenoh_reason

    said, inner = (
        "Can not create a new TCP listener bound to tcp/127.0.0.1:24473: [",
        "Address already in use (os error 98)",
    )
    places = (
        " at /root/.cargo/registry/src/zenoh-link-tcp-1.0.0/src/unicast.rs:61.",
        " at /root/.cargo/git/checkouts/zenoh/src/net/runtime/orchestrator.rs:388.",
    )
    raw = f"{said}{inner}{places[0]}]{places[1]}"
    assert zenoh_reason(Exception(raw)) == f"{said}{inner}]"  # Zenoh's words, without the places
    assert zenoh_reason(Exception("Timeout!")) == "Timeout!"
