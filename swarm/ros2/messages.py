"""ROS 2 message types, CDR and type hashes, from rosbags' stores; no ROS install.

API (callers pass plain numbers and names; rosbags' classes stay inside):

    DISTROS                                   the distros whose wire format is known
    typestore(distro="jazzy")                 rosbags' store of that distro's messages
    type_hash(msgtype, distro) -> str         "RIHS01_<64 hex>" (REP-2016)
    dds_type_name(msgtype) -> str             "geometry_msgs::msg::dds_::Twist_"
    msgdef(msgtype, distro) -> str            ros2msg text with its dependencies (MCAP schemas)
    build(msgtype, distro, **fields) -> msg   every field zero or empty but those given
    encode(msgtype, msg, distro) -> bytes     CDR little endian, 4-byte encapsulation header
    decode(msgtype, data, distro) -> msg      ValueError for bytes that are not such a message
    stamp(time_s) -> dict                     a builtin_interfaces/Time as fields for build
    yaw_quaternion(theta_rad) -> dict         a geometry_msgs/Quaternion as fields for build

``build`` takes nested fields as dicts: ``build("geometry_msgs/msg/Twist",
linear={"x": 0.5}, angular={"z": 0.1})``.
"""

from __future__ import annotations

import math
import struct
from functools import cache
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

# rmw_zenoh keys, attachments and liveliness tokens are the same for these
# (docs/design.md of its jazzy and kilted releases).
DISTROS = {"jazzy": Stores.ROS2_JAZZY, "kilted": Stores.ROS2_KILTED}
DEFAULT_DISTRO = "jazzy"
CDR_LE = b"\x00\x01\x00\x00"  # the encapsulation header of little-endian plain CDR
MAX_MESSAGE_BYTES = 1 << 20  # far above any message here; a larger payload is refused unread
# What bytes that are not a message raise in rosbags (it wraps its own errors
# in SerdeError; the others are kept in case a version does not).
BAD_CDR = (SerdeError, ValueError, IndexError, struct.error, UnicodeDecodeError, MemoryError, OverflowError)
_NUMPY = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


@cache
def typestore(distro: str = DEFAULT_DISTRO) -> Typestore:
    """rosbags' message store of ``distro``; ValueError for a distro not in DISTROS."""
    if distro not in DISTROS:
        raise ValueError(f"distro must be one of {', '.join(DISTROS)}, got {distro!r}")
    return get_typestore(DISTROS[distro])


def _known(msgtype: str, distro: str) -> Typestore:
    store = typestore(distro)
    if msgtype not in store.types:
        raise ValueError(f"msgtype {msgtype!r} is not a message of ROS 2 {distro}")
    return store


@cache
def type_hash(msgtype: str, distro: str = DEFAULT_DISTRO) -> str:
    """The type's REP-2016 hash as rmw_zenoh puts it in keys: ``RIHS01_<64 hex>``."""
    return str(_known(msgtype, distro).hash_rihs01(msgtype))


def dds_type_name(msgtype: str) -> str:
    """``pkg/msg/Name`` -> ``pkg::msg::dds_::Name_``, the type name rmw_zenoh's keys carry."""
    parts = msgtype.split("/")
    if len(parts) != 3 or not all(parts) or parts[1] != "msg":
        raise ValueError(f"msgtype must read package/msg/Name, got {msgtype!r}")
    return f"{parts[0]}::msg::dds_::{parts[2]}_"


@cache
def msgdef(msgtype: str, distro: str = DEFAULT_DISTRO) -> str:
    """The type's definition with its dependencies, as rosbag2 stores it in an
    MCAP schema (encoding ``ros2msg``, blocks apart by a line of 80 ``=``)."""
    text, _ = _known(msgtype, distro).generate_msgdef(msgtype, ros_version=2)
    return str(text)


def build(msgtype: str, distro: str = DEFAULT_DISTRO, **fields: Any) -> Any:
    """A message of ``msgtype`` with ``fields`` set (nested ones as dicts) and
    every other field zero, false or empty; ValueError for an unknown field."""
    store = _known(msgtype, distro)
    _, defs = store.fielddefs[msgtype]
    names = [name for name, _ in defs]
    unknown = sorted(set(fields) - set(names))
    if unknown:
        raise ValueError(f"{msgtype} has no field {unknown[0]!r} (fields: {', '.join(names)})")
    values = {}
    for name, desc in defs:
        given = fields.get(name)
        if desc[0] == Nodetype.NAME and (given is None or isinstance(given, dict)):
            values[name] = build(desc[1], distro, **(given or {}))
        elif name in fields:
            values[name] = given
        else:
            values[name] = _zero(desc, distro)
    return store.types[msgtype](**values)


def _zero(desc: tuple[Any, Any], distro: str) -> Any:
    kind, detail = desc
    if kind == Nodetype.BASE:
        base = detail[0]
        return "" if base in ("string", "wstring") else False if base == "bool" else 0.0 if "float" in base else 0
    if kind == Nodetype.NAME:
        return build(detail, distro)
    inner, length = detail
    if kind == Nodetype.ARRAY:
        if inner[0] == Nodetype.BASE and inner[1][0] in _NUMPY:
            return np.zeros(length, dtype=_NUMPY[inner[1][0]])
        return [_zero(inner, distro) for _ in range(length)]
    if inner[0] == Nodetype.BASE and inner[1][0] in _NUMPY:
        return np.zeros(0, dtype=_NUMPY[inner[1][0]])
    return []


def encode(msgtype: str, msg: Any, distro: str = DEFAULT_DISTRO) -> bytes:
    """The message as rmw_zenoh sends it: little-endian CDR after its 4-byte header."""
    return bytes(_known(msgtype, distro).serialize_cdr(msg, msgtype))


def decode(msgtype: str, data: bytes | bytearray | memoryview, distro: str = DEFAULT_DISTRO) -> Any:
    """The message in ``data``; ValueError (one line) for bytes that are not one."""
    store = _known(msgtype, distro)
    if len(data) > MAX_MESSAGE_BYTES:
        raise ValueError(f"{msgtype}: {len(data)} bytes, above {MAX_MESSAGE_BYTES}")
    if len(data) < 4 or bytes(data[:2]) not in (b"\x00\x00", b"\x00\x01"):
        raise ValueError(f"{msgtype}: no plain CDR encapsulation header")
    try:
        return store.deserialize_cdr(bytes(data), msgtype)
    except BAD_CDR as exc:
        text = " ".join(str(exc).split())[:120]
        raise ValueError(f"{msgtype}: not a CDR message of this type ({type(exc).__name__}: {text})") from None


def stamp(time_s: float) -> dict[str, int]:
    """``time_s`` (>= 0) as builtin_interfaces/Time fields (sec, nanosec)."""
    if not math.isfinite(time_s) or time_s < 0:
        raise ValueError(f"time_s must be finite and >= 0, got {time_s!r}")
    ns = round(time_s * 1e9)
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def yaw_quaternion(theta_rad: float) -> dict[str, float]:
    """A rotation of ``theta_rad`` about z (CCW, REP-103) as quaternion fields."""
    half = 0.5 * theta_rad
    return {"x": 0.0, "y": 0.0, "z": math.sin(half), "w": math.cos(half)}


def quaternion_yaw(q: Any) -> float:
    """The yaw (rad, CCW about z) of a geometry_msgs/Quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
