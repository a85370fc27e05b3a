"""The decoder's fast path (protocol.builders) changes no outcome: every
message of the protocol's examples, and each of them with one value or the
length changed in ways a forger would try, decodes to the same message (the
same values of the same types) or is refused with the same reason and words
as the checks one by one give."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import fields

import msgpack
import pytest

from formation_swarm.protocol.codec import MAX_TICK, DecodeError, Message, Rejections
from formation_swarm.protocol.messages import Command
from tests.unit.protocol.test_messages import EXAMPLES

# Values a forger tries in any field: other types, the bounds and one beyond, NaN and inf.
ODD = [
    1.0,
    -0.0,
    0,
    1,
    255,
    256,
    -1,
    MAX_TICK,
    MAX_TICK + 1,
    True,
    False,
    None,
    "x",
    b"x",
    [],
    [1.0, 2.0, 3.0],
    [1.0, 2.0],
    [1, 2.0],
    [True, 2.0],
    [1.0, math.nan],
    [1e308, 1e308],  # each finite, their sum not
    [[1, 1.0, 0.5, 0.5]],
    math.nan,
    math.inf,
    1e308,
    {"a": 1},
]


@contextmanager
def _checks_one_by_one(cls: type[Message]) -> Iterator[None]:
    """Decoding of ``cls`` without its fast path."""
    names = cls._names()
    type.__setattr__(cls, "_DECODER", (names, lambda _raw: None))
    try:
        yield
    finally:
        type.__delattr__(cls, "_DECODER")


def _outcome(cls: type[Message], payload: bytes) -> tuple[str, object]:
    try:
        msg = cls.from_bytes(payload)
    except DecodeError as exc:
        return "refused", (exc.reason, str(exc))
    values = [getattr(msg, f.name) for f in fields(msg)]
    return "taken", (type(msg), repr(values), [type(v) for v in values])


def _forgeries(msg: Message) -> Iterator[bytes]:
    raw = msgpack.unpackb(msg.to_bytes())
    yield msg.to_bytes()
    for k in range(len(raw)):
        for odd in ODD:
            yield msgpack.packb([*raw[:k], odd, *raw[k + 1 :]])
    yield msgpack.packb(raw[:-1])
    yield msgpack.packb([*raw, 1.0])


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda m: type(m).__name__)
def test_the_fast_path_decides_as_the_checks_do(example: Message) -> None:
    cls = type(example)
    payloads = list(_forgeries(example))
    fast = [_outcome(cls, p) for p in payloads]
    with _checks_one_by_one(cls):
        slow = [_outcome(cls, p) for p in payloads]
    assert fast == slow
    assert fast[0] == ("taken", _outcome(cls, example.to_bytes())[1])
    assert cls.from_bytes(example.to_bytes()) == example
    taken = sum(kind == "taken" for kind, _ in fast)
    assert 1 < taken < len(fast)  # both ways were taken


def test_a_command_is_built_as_its_class_builds_it() -> None:
    """The message the fast path builds (without __init__) equals, hashes and
    prints as one made by keyword, and stays frozen."""
    made = Command(sender=3, seq=5, tick=4, left_mps=0.5, right_mps=-0.25, formation=1, done=False)
    got = Rejections().decode(Command, made.to_bytes(), sender=3)
    assert (got, hash(got), repr(got)) == (made, hash(made), repr(made))
    with pytest.raises(AttributeError):
        got.seq = 6  # type: ignore[misc]
