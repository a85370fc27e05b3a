"""Every message that crosses the wire, defined once.

Each message is a frozen dataclass encoded with msgpack as a list::

    [tag, version, sender, seq, tick, field_1, field_2, ...]

``sender`` is the robot id (0 for the world), ``seq`` the sender's sequence
number on that key, ``tick`` the simulation tick. ``from_bytes`` validates
everything (type, length, version, ranges, NaN/inf, size) and raises
:class:`DecodeError` with a reason; processes call :meth:`Rejections.decode`,
which counts the reason and returns None instead, so bad input never kills a
process nor reaches its state.

Streams that only feed the logger (telemetry, ground truth) travel in
batches: :class:`BatchPublisher` gathers encoded messages for a few
milliseconds of wall time into one ``[BATCH_TAG, version, [msg, ...]]``
payload, and :meth:`Rejections.decode_batch` takes it apart.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any, ClassVar, TypeVar

import msgpack

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


def _float(name: str, v: Any) -> float:
    if type(v) is float and math.isfinite(v):
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise DecodeError("wrong type", f"{name} must be a number, got {type(v).__name__}")
    f = float(v)
    if not math.isfinite(f):
        raise DecodeError("not finite", f"{name} is {f}")
    return f


def _opt_float(name: str, v: Any) -> float | None:
    return None if v is None else _float(name, v)


def _int_in(lo: int, hi: int) -> Callable[[str, Any], int]:
    def check(name: str, v: Any) -> int:
        if type(v) is int and lo <= v <= hi:
            return v
        if isinstance(v, bool) or not isinstance(v, int):
            raise DecodeError("wrong type", f"{name} must be an integer, got {type(v).__name__}")
        if not lo <= v <= hi:
            raise DecodeError("out of range", f"{name}={v} not in [{lo}, {hi}]")
        return v

    return check


def _bool(name: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise DecodeError("wrong type", f"{name} must be a boolean, got {type(v).__name__}")
    return v


def _floats(n: int, optional: bool = False) -> Callable[[str, Any], tuple[float, ...] | None]:
    def check(name: str, v: Any) -> tuple[float, ...] | None:
        if v is None and optional:
            return None
        if not isinstance(v, (list, tuple)) or len(v) != n:
            raise DecodeError("wrong shape", f"{name} must be a list of {n} numbers")
        for x in v:
            if type(x) is not float or not math.isfinite(x):
                return tuple(_float(f"{name}[{i}]", x) for i, x in enumerate(v))
        return tuple(v)

    return check


def _records(*item_checks: Callable[[str, Any], Any]) -> Callable[[str, Any], tuple[tuple[Any, ...], ...]]:
    n = len(item_checks)

    def check(name: str, v: Any) -> tuple[tuple[Any, ...], ...]:
        if not isinstance(v, (list, tuple)):
            raise DecodeError("wrong type", f"{name} must be a list")
        if len(v) > MAX_ITEMS:
            raise DecodeError("too many items", f"{name} has {len(v)} > {MAX_ITEMS}")
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

    return check


def _one_of(*allowed: str) -> Callable[[str, Any], str]:
    def check(name: str, v: Any) -> str:
        if v not in allowed:
            raise DecodeError("out of range", f"{name}={v!r} not one of {allowed}")
        return v

    return check


_robot = _int_in(1, MAX_ROBOT_ID)
_count = _int_in(0, MAX_TICK)
_code = _int_in(0, 255)

T = TypeVar("T", bound="Message")


@dataclass(frozen=True, slots=True)
class Message:
    sender: int
    seq: int
    tick: int

    TAG: ClassVar[int] = -1
    CHECKS: ClassVar[tuple[Callable[[str, Any], Any], ...]] = ()
    SENDERS: ClassVar[tuple[int, int]] = (0, MAX_ROBOT_ID)

    def to_bytes(self) -> bytes:
        return msgpack.packb([self.TAG, VERSION, *[getattr(self, n) for n in self._names()]], use_bin_type=True)

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
        if raw[0] != cls.TAG:
            raise DecodeError("wrong message type", f"tag {raw[0]!r}, expected {cls.TAG} ({cls.__name__})")
        if raw[1] != VERSION:
            raise DecodeError("unknown version", f"{raw[1]!r}, expected {VERSION}")
        names = cls._names()
        if len(raw) != 2 + len(names):
            raise DecodeError("wrong length", f"{cls.__name__} has {len(names)} fields, got {len(raw) - 2}")
        sender, seq, tick = raw[2], raw[3], raw[4]
        lo, hi = cls.SENDERS
        if type(sender) is not int or not lo <= sender <= hi:
            _int_in(lo, hi)("sender", sender)
        if type(seq) is not int or not 0 <= seq <= MAX_TICK:
            _count("seq", seq)
        if type(tick) is not int or not 0 <= tick <= MAX_TICK:
            _count("tick", tick)
        values = [c(n, v) for c, n, v in zip(cls.CHECKS, names[3:], raw[5:], strict=True)]
        return cls(sender, seq, tick, *values)

    @classmethod
    def _names(cls) -> tuple[str, ...]:
        cached = cls.__dict__.get("_NAMES")
        if cached is None:
            cached = tuple(f.name for f in fields(cls))
            type.__setattr__(cls, "_NAMES", cached)
        return cached


@dataclass(frozen=True, slots=True)
class Observation(Message):
    """World -> agent, tick k: what the robot's sensors give it.

    pose: the robot's own odometry (x_m, y_m, theta_rad), world frame.
    readings: markers in view, (robot_id, rho_m, phi_rad, beta_rad) each.
    obstacles: obstacles in sensing range (distance_m, bearing_rad, radius_m),
    only for robots that sense them (the leader).
    """

    time_s: float
    pose: tuple[float, float, float]
    readings: tuple[tuple[int, float, float, float], ...]
    obstacles: tuple[tuple[float, float, float], ...]

    TAG: ClassVar[int] = 1
    SENDERS: ClassVar[tuple[int, int]] = (WORLD_ID, WORLD_ID)
    CHECKS = (_float, _floats(3), _records(_robot, _float, _float, _float), _records(_float, _float, _float))


@dataclass(frozen=True, slots=True)
class Command(Message):
    """Agent -> world, answer to tick k: wheel speeds (m/s) and the agent's state.

    formation: the formation code the robot is flying; done: the leader has
    finished its path (the run may end).
    """

    left_mps: float
    right_mps: float
    formation: int
    done: bool

    TAG: ClassVar[int] = 2
    SENDERS: ClassVar[tuple[int, int]] = (1, MAX_ROBOT_ID)
    CHECKS = (_float, _float, _code, _bool)


@dataclass(frozen=True, slots=True)
class FormationCode(Message):
    """Leader -> one follower: the formation to fly, repeated (agents.leader.CodeRepeats)."""

    code: int

    TAG: ClassVar[int] = 3
    SENDERS: ClassVar[tuple[int, int]] = (1, MAX_ROBOT_ID)
    CHECKS = (_code,)


@dataclass(frozen=True, slots=True)
class Telemetry(Message):
    """Agent -> logger: a follower's estimator and controller state at tick k.

    Points are in the follower's frame (x right, y ahead), m. None where the
    quantity does not exist this tick (no reading, filter not started).
    target_cov: (xx, xy, yy) of the EKF target estimate, m^2.
    """

    time_s: float
    reference: int
    formation: int
    measured: tuple[float, float] | None
    estimate: tuple[float, float] | None
    target_cov: tuple[float, float, float] | None
    rho_m: float | None
    alpha_rad: float | None
    vn: float | None
    left_mps: float
    right_mps: float
    steering_to: int
    changing: bool
    obs_dropped: int
    formation_dropped: int
    rejected: int

    TAG: ClassVar[int] = 4
    SENDERS: ClassVar[tuple[int, int]] = (1, MAX_ROBOT_ID)
    CHECKS = (
        _float, _robot, _code, _floats(2, True), _floats(2, True), _floats(3, True),
        _opt_float, _opt_float, _opt_float, _float, _float, _int_in(0, 3), _bool, _count, _count, _count,
    )  # fmt: skip


@dataclass(frozen=True, slots=True)
class Truth(Message):
    """World -> logger: ground truth at tick k (before the step).

    robots: (robot_id, x_m, y_m, theta_rad, alive) each, world frame.
    targets: (follower_id, x_m, y_m) true virtual target of each follower's
    current slot, world frame.
    """

    time_s: float
    robots: tuple[tuple[int, float, float, float, bool], ...]
    targets: tuple[tuple[int, float, float], ...]

    TAG: ClassVar[int] = 5
    SENDERS: ClassVar[tuple[int, int]] = (WORLD_ID, WORLD_ID)
    CHECKS = (_float, _records(_robot, _float, _float, _float, _bool), _records(_robot, _float, _float))


@dataclass(frozen=True, slots=True)
class Status(Message):
    """World -> all: progress; state "done" ends the run for every process."""

    time_s: float
    state: str
    total_ticks: int

    TAG: ClassVar[int] = 6
    SENDERS: ClassVar[tuple[int, int]] = (WORLD_ID, WORLD_ID)
    CHECKS = (_float, _one_of("waiting", "running", "done"), _count)


def pack_batch(encoded: list[bytes]) -> bytes:
    """Encoded messages in one payload (see :class:`BatchPublisher`)."""
    return msgpack.packb([BATCH_TAG, VERSION, encoded], use_bin_type=True)


class BatchPublisher:
    """Puts to one key gathered into batches, for streams off the control path.

    A message goes out with the ones before it once ``window_s`` of wall time
    has passed since the last put, or when the batch is full, so at 20 Hz every
    message leaves at once and in a fast lockstep run one put carries many
    ticks. ``flush`` sends what is held; ``close`` flushes and then sends an
    empty batch, which tells the receiver that the stream has ended (it comes
    after the data, whereas a liveliness token's end may overtake it).
    """

    def __init__(self, pub: Any, window_s: float = 0.02, max_bytes: int = MAX_PAYLOAD_BYTES // 2,
                 clock: Callable[[], float] = time.monotonic) -> None:  # fmt: skip
        if not window_s >= 0.0:
            raise ValueError(f"window_s must be >= 0, got {window_s!r}")
        if not 0 < max_bytes <= MAX_PAYLOAD_BYTES // 2:
            raise ValueError(f"max_bytes must be in (0, {MAX_PAYLOAD_BYTES // 2}], got {max_bytes!r}")
        self.pub = pub
        self.window_s = window_s
        self.max_bytes = max_bytes
        self.clock = clock
        self.items: list[bytes] = []
        self.size = 0
        self.last_put = -math.inf

    def put(self, payload: bytes) -> None:
        if self.size + len(payload) > self.max_bytes:
            self.flush()
        self.items.append(payload)
        self.size += len(payload)
        if len(self.items) >= MAX_BATCH_ITEMS or self.clock() - self.last_put >= self.window_s:
            self.flush()

    def flush(self) -> None:
        if self.items:
            self.pub.put(pack_batch(self.items))
            self.items, self.size = [], 0
        self.last_put = self.clock()

    def close(self) -> None:
        self.flush()
        self.pub.put(pack_batch([]))


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
            items = _unpack_batch(payload)
        except DecodeError as exc:
            self.by_reason[exc.reason] += 1
            return None
        out = []
        for item in items:
            msg = self.decode(cls, item, sender)
            if msg is not None:
                out.append(msg)
        return out


def _unpack_batch(payload: bytes) -> list[bytes]:
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise DecodeError("oversized", f"{len(payload)} bytes > {MAX_PAYLOAD_BYTES}")
    try:
        raw = msgpack.unpackb(payload, raw=False, max_array_len=MAX_BATCH_ITEMS, max_map_len=0)
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError) as exc:
        raise DecodeError("not msgpack", type(exc).__name__) from None
    if not isinstance(raw, list) or len(raw) != 3:
        raise DecodeError("wrong type", "a batch is a msgpack list [tag, version, items]")
    if raw[0] != BATCH_TAG:
        raise DecodeError("wrong message type", f"tag {raw[0]!r}, expected a batch ({BATCH_TAG})")
    if raw[1] != VERSION:
        raise DecodeError("unknown version", f"{raw[1]!r}, expected {VERSION}")
    items = raw[2]
    if not isinstance(items, list) or not all(isinstance(b, bytes) for b in items):
        raise DecodeError("wrong type", "a batch's items must be a list of encoded messages")
    return items
