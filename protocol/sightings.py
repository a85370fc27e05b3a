"""Every robot's observation of a tick, for the ROS 2 bridge: the world puts
the very bytes it sent each robot (an Observation, protocol.messages) on
``Keys.sightings`` too, gathered with the robot's id, only when a bridge is
planned (``swarm run --ros2``).

A payload is ``[SIGHTINGS_TAG, version, [[robot_id, observation], ...]]``,
at most ``MAX_PAYLOAD_BYTES``: a tick takes as many puts as its
observations need (about 16 kB each). The bridge could not subscribe each
robot's ``obs`` key instead: the world takes a robot's observations without
a subscriber for its agent's session gone (nodes.world.sessions), and a
second subscriber would hide that.
"""

from __future__ import annotations

import msgpack

from formation_swarm.protocol.codec import (
    MAX_BATCH_ITEMS,
    MAX_PAYLOAD_BYTES,
    VERSION,
    WORLD_ID,
    DecodeError,
    Rejections,
    unpack_tagged,
)
from formation_swarm.protocol.keys import MAX_ROBOT_ID
from formation_swarm.protocol.messages import Observation

SIGHTINGS_TAG = 101
CHUNK_BYTES = MAX_PAYLOAD_BYTES // 2  # a put closes past this; one observation is far smaller


def pack(encoded: list[tuple[int, bytes]]) -> list[bytes]:
    """The payloads that carry ``encoded`` ((robot id, Observation bytes) each), in order."""
    out: list[bytes] = []
    chunk: list[tuple[int, bytes]] = []
    size = 0
    for rid, payload in encoded:
        if chunk and (size + len(payload) > CHUNK_BYTES or len(chunk) >= MAX_BATCH_ITEMS):
            out.append(msgpack.packb([SIGHTINGS_TAG, VERSION, chunk], use_bin_type=True))
            chunk, size = [], 0
        chunk.append((rid, payload))
        size += len(payload) + 4
    if chunk:
        out.append(msgpack.packb([SIGHTINGS_TAG, VERSION, chunk], use_bin_type=True))
    return out


def unpack(payload: bytes, rejections: Rejections) -> list[tuple[int, Observation]]:
    """The (robot id, Observation) pairs of one payload; what does not decode is
    counted in ``rejections`` (the whole payload, or one pair)."""
    try:
        items = _items(payload)
    except DecodeError as exc:
        rejections.reject(exc.reason)
        return []
    out = []
    for item in items:
        if not (isinstance(item, list) and len(item) == 2 and type(item[0]) is int and isinstance(item[1], bytes)):
            rejections.reject("wrong type")
        elif not 1 <= item[0] <= MAX_ROBOT_ID:
            rejections.reject("out of range")
        elif (obs := rejections.decode(Observation, item[1], WORLD_ID)) is not None:
            out.append((item[0], obs))
    return out


def _items(payload: bytes) -> list[object]:
    items = unpack_tagged(payload, SIGHTINGS_TAG, "a sightings payload")
    if not isinstance(items, list):
        raise DecodeError("wrong type", "the sightings' items must be a list")
    return items
