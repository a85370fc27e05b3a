"""The envelope every message shares, its validation, and decoding at a
process boundary.

A message is a msgpack array::

    [tag, version, sender, seq, tick, field_1, field_2, ...]

``sender`` is the robot id (0 for the world), ``seq`` the sender's sequence
number, ``tick`` the simulation tick. :meth:`Message.from_bytes` validates
everything (type, length, version, ranges, NaN/inf, size) and raises
:class:`DecodeError` with a reason; processes call :meth:`Rejections.decode`,
which counts the reason and returns None instead, so bad input never kills a
process nor reaches its state. A batch (``[BATCH_TAG, version, [msg, ...]]``,
see protocol.batch) is taken apart by :meth:`Rejections.decode_batch`.

The message types are in protocol.messages; docs/protocol.md describes the
wire for writers of agents in other languages.
"""

from __future__ import annotations

import math
import operator
import re
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any, ClassVar, TypeVar

import msgpack

from formation_swarm.protocol.builders import builder, fast_decoder
from formation_swarm.protocol.keys import MAX_ROBOT_ID

VERSION = 1
# Every message of ours fits with room to spare (swarm.scenario bounds robots
# and obstacles); protocol.session explains why links carry no more than ~40 KiB.
MAX_PAYLOAD_BYTES = 32 * 1024
MAX_ITEMS = 1024  # longest list in any message (robots, readings, obstacles)
WORLD_ID = 0
MAX_TICK = 2**53
BATCH_TAG = 100
MAX_BATCH_ITEMS = 256


class DecodeError(ValueError):
    """A payload that is not a valid message; ``reason`` is short and countable."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


# -- field checkers: each takes (name, value) and returns the clean value ------


# Every check tests the common case first (a finite float, an int in range)
# and builds a field name or an error only on the way to a rejection: these
# run on every message of every tick.

_FLOAT = frozenset((float,))
_INT = frozenset((int,))
_BOOL = frozenset((bool,))
_LIST = frozenset((list,))


def number(name: str, v: Any) -> float:
    if type(v) is float and math.isfinite(v):
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise DecodeError("wrong type", f"{name} must be a number, got {type(v).__name__}")
    f = float(v)
    if not math.isfinite(f):
        raise DecodeError("not finite", f"{name} is {f}")
    return f


# A check's ``fast``: a test of a value ``{v}`` that holds exactly when the check
# returns the value as it is (protocol.builders writes it into a class's decoder).
number.fast = "type({v}) is float and isfinite({v})"  # type: ignore[attr-defined]


def opt_number(name: str, v: Any) -> float | None:
    return None if v is None else number(name, v)


def int_in(lo: int, hi: int) -> Callable[[str, Any], int]:
    def check(name: str, v: Any) -> int:
        if type(v) is int and lo <= v <= hi:
            return v
        if isinstance(v, bool) or not isinstance(v, int):
            raise DecodeError("wrong type", f"{name} must be an integer, got {type(v).__name__}")
        if not lo <= v <= hi:
            raise DecodeError("out of range", f"{name}={v} not in [{lo}, {hi}]")
        return v

    check.bounds = (lo, hi)  # type: ignore[attr-defined]  # for records' column checks
    check.fast = f"type({{v}}) is int and {int(lo)} <= {{v}} <= {int(hi)}"  # type: ignore[attr-defined]
    return check


def boolean(name: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise DecodeError("wrong type", f"{name} must be a boolean, got {type(v).__name__}")
    return v


boolean.fast = "type({v}) is bool"  # type: ignore[attr-defined]  # bool has no subclasses


def numbers(n: int, optional: bool = False) -> Callable[[str, Any], tuple[float, ...] | None]:
    def check(name: str, v: Any) -> tuple[float, ...] | None:
        if v is None and optional:
            return None
        if not isinstance(v, (list, tuple)) or len(v) != n:
            raise DecodeError("wrong shape", f"{name} must be a list of {n} numbers")
        if _FLOAT.issuperset(map(type, v)) and math.isfinite(sum(v)):
            return tuple(v)
        return tuple(number(f"{name}[{i}]", x) for i, x in enumerate(v))

    # The common case written out for the fast decoder (protocol.builders): n floats, a finite sum.
    items = [f"{{v}}[{i}]" for i in range(n)]
    whole = " and ".join([f"type({{v}}) is list and len({{v}}) == {n}", *(f"type({x}) is float" for x in items)])
    check.fast = f"{'{v} is None or ' if optional else ''}{whole} and isfinite({' + '.join(items)})"  # type: ignore[attr-defined]
    check.fast_value = "({v} and tuple({v}))" if optional else "tuple({v})"  # type: ignore[attr-defined]
    return check


def _column_ok(check: Callable[[str, Any], Any], column: tuple[Any, ...]) -> bool:
    """Whether every value of a column passes ``check`` as it is (the common
    case, tested in one go: a few calls per column instead of one per value).
    False sends the records through the checks one by one, which decide."""
    # The types are taken in C (map, a set): no Python call per value.
    if check is number:
        # A NaN or an inf makes the sum NaN or inf; so can a sum that overflows,
        # which only costs the slow path.
        return _FLOAT.issuperset(map(type, column)) and math.isfinite(sum(column))
    if check is boolean:
        return _BOOL.issuperset(map(type, column))
    bounds = getattr(check, "bounds", None)
    if bounds is not None:
        return _INT.issuperset(map(type, column)) and bounds[0] <= min(column) and max(column) <= bounds[1]
    return False


def records(*item_checks: Callable[[str, Any], Any]) -> Callable[[str, Any], tuple[tuple[Any, ...], ...]]:
    n = len(item_checks)

    def check(name: str, v: Any) -> tuple[tuple[Any, ...], ...]:
        if not isinstance(v, (list, tuple)):
            raise DecodeError("wrong type", f"{name} must be a list")
        if len(v) > MAX_ITEMS:
            raise DecodeError("too many items", f"{name} has {len(v)} > {MAX_ITEMS}")
        if v and _LIST.issuperset(map(type, v)) and {n}.issuperset(map(len, v)):
            for c, col in zip(item_checks, zip(*v, strict=True), strict=True):
                if not _column_ok(c, col):
                    break
            else:
                return tuple(map(tuple, v))
        out = []
        for i, rec in enumerate(v):
            if not isinstance(rec, (list, tuple)) or len(rec) != n:
                raise DecodeError("wrong shape", f"{name}[{i}] must be a list of {n}")
            try:
                out.append(tuple([c(name, x) for c, x in zip(item_checks, rec, strict=True)]))
            except DecodeError:
                for c, x in zip(item_checks, rec, strict=True):
                    c(f"{name}[{i}]", x)  # the same rejection, naming the record
                raise
        return tuple(out)

    check.fast, check.fast_value = "type({v}) is list and not {v}", "()"  # type: ignore[attr-defined]  # none: ()
    return check


def one_of(*allowed: str) -> Callable[[str, Any], str]:
    def check(name: str, v: Any) -> str:
        if v not in allowed:
            raise DecodeError("out of range", f"{name}={v!r} not one of {allowed}")
        return v

    return check


def named_numbers(max_items: int, name: re.Pattern[str]) -> Callable[[str, Any], tuple[tuple[str, float], ...]]:
    """An array of at most ``max_items`` [name, float] pairs, each name matching
    ``name`` and given once (a Telemetry's extras)."""
    pair = records(text(name), number)

    def check(field: str, v: Any) -> tuple[tuple[str, float], ...]:
        if isinstance(v, (list, tuple)) and len(v) > max_items:
            raise DecodeError("too many items", f"{field} has {len(v)} > {max_items}")
        out = pair(field, v)
        if len({n for n, _ in out}) != len(out):
            raise DecodeError("out of range", f"{field} names a value twice")
        return out

    check.fast, check.fast_value = pair.fast, pair.fast_value  # type: ignore[attr-defined]  # none: ()
    return check


def text(pattern: re.Pattern[str]) -> Callable[[str, Any], str]:
    """A string that ``pattern`` matches whole."""

    def check(name: str, v: Any) -> str:
        if type(v) is not str:
            raise DecodeError("wrong type", f"{name} must be a string, got {type(v).__name__}")
        if pattern.fullmatch(v) is None:
            raise DecodeError("out of range", f"{name}={v[:40]!r} does not match {pattern.pattern}")
        return v

    return check


robot_id = int_in(1, MAX_ROBOT_ID)
count = int_in(0, MAX_TICK)
formation_code = int_in(0, 255)

T = TypeVar("T", bound="Message")


@dataclass(frozen=True, slots=True, kw_only=True)
class Message:
    """The header every message starts with; a subclass adds its fields, its
    ``TAG``, one checker per field in ``CHECKS`` and the ``SENDERS`` range.

    ``OPTIONAL``: how many of the last fields a sender may leave out (each an
    array; left out, it is empty). A field added this way keeps the version:
    a peer that does not know it neither sends it nor is sent it empty.
    """

    sender: int
    seq: int
    tick: int

    TAG: ClassVar[int] = -1
    CHECKS: ClassVar[tuple[Callable[[str, Any], Any], ...]] = ()
    SENDERS: ClassVar[tuple[int, int]] = (0, MAX_ROBOT_ID)
    OPTIONAL: ClassVar[int] = 0

    def to_bytes(self) -> bytes:
        """The message on the wire; ValueError for a seq or a tick that no decoder
        takes (outside 0..MAX_TICK, or not an int). The sender is not checked:
        tests forge messages of the wrong sender with it."""
        values = [self.TAG, VERSION, *self._getter()(self)]
        seq, tick = values[3], values[4]
        # Exact int types, as the decoder wants: True or 2.0 would decode as a wrong type.
        if not (type(seq) is int and 0 <= seq <= MAX_TICK and type(tick) is int and 0 <= tick <= MAX_TICK):
            for name, value in (("seq", seq), ("tick", tick)):
                if type(value) is not int or not 0 <= value <= MAX_TICK:
                    raise ValueError(f"{type(self).__name__}.{name} must be an int in [0, 2^53], got {value!r}")
        if self.OPTIONAL:
            for _ in range(self.OPTIONAL):  # empty optional fields at the end are left out
                if values[-1]:
                    break
                values.pop()
        return msgpack.packb(values, use_bin_type=True)

    @classmethod
    def from_bytes(cls: type[T], payload: bytes) -> T:
        if len(payload) > MAX_PAYLOAD_BYTES:
            raise DecodeError("oversized", f"{len(payload)} bytes > {MAX_PAYLOAD_BYTES}")
        try:
            raw = msgpack.unpackb(payload, raw=False, strict_map_key=True, max_array_len=MAX_ITEMS * 8)
        except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError) as exc:
            raise DecodeError("not msgpack", type(exc).__name__) from None
        if not isinstance(raw, list) or len(raw) < 5:
            raise DecodeError("wrong type", "payload must be a msgpack list with a header")
        if type(raw[0]) is not int or raw[0] != cls.TAG:  # 2.0 and True compare equal to ints
            raise DecodeError("wrong message type", f"tag {raw[0]!r}, expected {cls.TAG} ({cls.__name__})")
        if type(raw[1]) is not int or raw[1] != VERSION:
            raise DecodeError("unknown version", f"{raw[1]!r}, expected {VERSION}")
        names, fast = cls.__dict__.get("_DECODER") or cls._decoder()
        if len(raw) != 2 + len(names):
            if not 0 < 2 + len(names) - len(raw) <= cls.OPTIONAL:
                raise DecodeError("wrong length", f"{cls.__name__} has {len(names)} fields, got {len(raw) - 2}")
            raw += [[]] * (2 + len(names) - len(raw))  # the optional fields left out: empty
        msg = fast(raw)  # every value as its check returns it (the common case), or None
        if msg is not None:
            return msg  # type: ignore[no-any-return]
        sender, seq, tick = raw[2], raw[3], raw[4]
        lo, hi = cls.SENDERS
        if type(sender) is not int or not lo <= sender <= hi:
            int_in(lo, hi)("sender", sender)
        if type(seq) is not int or not 0 <= seq <= MAX_TICK:
            count("seq", seq)
        if type(tick) is not int or not 0 <= tick <= MAX_TICK:
            count("tick", tick)
        values = [c(n, v) for c, n, v in zip(cls.CHECKS, names[3:], raw[5:], strict=True)]
        return cls._builder()(sender, seq, tick, *values)

    @classmethod
    def _names(cls) -> tuple[str, ...]:
        cached = cls.__dict__.get("_NAMES")
        if cached is None:
            cached = tuple(f.name for f in fields(cls))
            type.__setattr__(cls, "_NAMES", cached)
        return cached

    @classmethod
    def _builder(cls: type[T]) -> Callable[..., T]:
        """A function of the fields' values in wire order that returns the
        message (protocol.builders): built without a dict of its fields made
        and unpacked each time, nor the frozen ``__init__`` run."""
        cached = cls.__dict__.get("_BUILDER")
        if cached is None:
            cached = builder(cls, cls._names())
            type.__setattr__(cls, "_BUILDER", cached)
        return cached  # type: ignore[no-any-return]

    @classmethod
    def _decoder(cls) -> tuple[tuple[str, ...], Callable[[list[Any]], Any]]:
        """The field names and the fast decoder of the common case (protocol.builders), made once."""
        lo, hi = cls.SENDERS
        fast = fast_decoder(
            cls._names(), ((lo, hi), (0, MAX_TICK), (0, MAX_TICK)), cls.CHECKS, cls._builder(), cls.__name__
        )
        type.__setattr__(cls, "_DECODER", (cls._names(), fast))
        return cls._names(), fast

    @classmethod
    def _getter(cls) -> Callable[[Message], tuple[Any, ...]]:
        """The fields' values in wire order, taken in one call."""
        cached = cls.__dict__.get("_GETTER")
        if cached is None:
            cached = operator.attrgetter(*cls._names())
            type.__setattr__(cls, "_GETTER", cached)
        return cached  # type: ignore[no-any-return]


def unpack_tagged(payload: bytes, tag: int, what: str) -> object:
    """The items of a ``[tag, version, items]`` payload named ``what``; DecodeError if not one."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise DecodeError("oversized", f"{len(payload)} bytes > {MAX_PAYLOAD_BYTES}")
    try:
        raw = msgpack.unpackb(payload, raw=False, max_array_len=MAX_BATCH_ITEMS, max_map_len=0)
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError) as exc:
        raise DecodeError("not msgpack", type(exc).__name__) from None
    if not isinstance(raw, list) or len(raw) != 3:
        raise DecodeError("wrong type", f"{what} is a msgpack list [tag, version, items]")
    if type(raw[0]) is not int or raw[0] != tag:
        raise DecodeError("wrong message type", f"tag {raw[0]!r}, expected {what} ({tag})")
    if type(raw[1]) is not int or raw[1] != VERSION:
        raise DecodeError("unknown version", f"{raw[1]!r}, expected {VERSION}")
    return raw[2]


def unpack_batch(payload: bytes) -> list[bytes]:
    items = unpack_tagged(payload, BATCH_TAG, "a batch")  # DecodeError if it is not one
    if not isinstance(items, list) or not all(isinstance(b, bytes) for b in items):
        raise DecodeError("wrong type", "a batch's items must be a list of encoded messages")
    return items


class Rejections:
    """Counts rejected payloads by reason; decoding at a process boundary."""

    def __init__(self) -> None:
        self.by_reason: Counter[str] = Counter()

    @property
    def total(self) -> int:
        return sum(self.by_reason.values())

    def reject(self, reason: str) -> None:
        self.by_reason[reason] += 1

    def decode(self, cls: type[T], payload: bytes, sender: int | None = None) -> T | None:
        """The message, or None with the reason counted. ``sender``, when given,
        is the id the key says the message comes from."""
        try:
            msg = cls.from_bytes(payload)
        except DecodeError as exc:
            self.by_reason[exc.reason] += 1
            return None
        if sender is not None and msg.sender != sender:
            self.by_reason["sender mismatch"] += 1
            return None
        return msg

    def decode_batch(self, cls: type[T], payload: bytes, sender: int | None = None) -> list[T] | None:
        """The valid messages of a batch of ``cls`` ([] for the end-of-stream
        batch), or None for a payload that is not a batch (one rejection
        counted); each bad message inside counts as one rejection."""
        try:
            items = unpack_batch(payload)
        except DecodeError as exc:
            self.by_reason[exc.reason] += 1
            return None
        out = []
        for item in items:
            msg = self.decode(cls, item, sender)
            if msg is not None:
                out.append(msg)
        return out
