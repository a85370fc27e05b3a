"""The Observations of a tick encoded together: for each robot the very bytes
``Observation.to_bytes()`` gives (protocol.messages: a msgpack array), made
for every camera at once with numpy instead of one msgpack call on Python
tuples per robot (a third of the world's tick at 1,000 robots).

msgpack writes a float as 0xcb and its 8 bytes big-endian, an array of
fewer than 16 items as 0x90 + n (else 0xdc and a 16-bit length), and an
integer in the fewest bytes: below 128 as itself, below 256 as 0xcc and a
byte, below 65536 as 0xcd and two. tests/unit/world/test_wire.py holds
these bytes equal to msgpack's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import msgpack
import numpy as np

from formation_swarm.protocol.messages import MAX_ITEMS, VERSION, WORLD_ID, Observation
from formation_swarm.world.camera import pose_array

if TYPE_CHECKING:
    from formation_swarm.world.engine import Observed, WorldEngine

# [tag, version, sender, seq, tick, time_s, pose, readings, obstacles]: 9 items,
# the first three small integers (each its own byte).
_HEAD = bytes((0x99, Observation.TAG, VERSION, WORLD_ID))
_MAX_ID = 0xFFFF


# One reading as msgpack writes it at its longest: [id, rho, phi, beta] with an id
# of two bytes (0xcd); shorter ids leave out the "kind" and then the "high" byte.
_READING = np.dtype(
    [
        ("array", "u1"),
        ("kind", "u1"),
        ("high", "u1"),
        ("low", "u1"),
        ("f_rho", "u1"),
        ("rho", ">f8"),
        ("f_phi", "u1"),
        ("phi", ">f8"),
        ("f_beta", "u1"),
        ("beta", ">f8"),
    ]
)
_POSE = np.dtype(
    [("array", "u1"), ("f_x", "u1"), ("x", ">f8"), ("f_y", "u1"), ("y", ">f8"), ("f_t", "u1"), ("t", ">f8")]
)


def readings_bytes(
    ids: np.ndarray, rho: np.ndarray, phi: np.ndarray, beta: np.ndarray, counts: Sequence[int]
) -> tuple[bytes, list[int]]:
    """The readings [robot_id, rho, phi, beta] of several cameras one after the
    other, ``counts`` of them each, and where each camera's start (one offset
    more than cameras: the end)."""
    n = len(ids)
    if n and (ids.min() < 0 or ids.max() > _MAX_ID):
        raise ValueError(f"a robot id of a reading is outside [0, {_MAX_ID}]")
    rows = np.empty(n, _READING)
    rows["array"] = 0x94
    rows["kind"] = 0xCD
    rows["high"] = ids >> 8
    rows["low"] = ids & 0xFF
    rows["f_rho"] = rows["f_phi"] = rows["f_beta"] = 0xCB
    rows["rho"], rows["phi"], rows["beta"] = rho, phi, beta
    wide = ids >= 0x100
    ends = np.cumsum(np.asarray(counts, dtype=np.int64))
    if wide.all():  # every id in two bytes: the rows as they are
        return rows.tobytes(), [0, *(ends * _READING.itemsize).tolist()]
    fix = ids < 0x80
    rows["high"][~wide & ~fix] = 0xCC
    flat = rows.view(np.uint8).reshape(n, _READING.itemsize)
    keep = np.ones(flat.shape, bool)
    keep[:, 1] = wide  # 0xcd: two bytes follow
    keep[:, 2] = ~fix  # 0xcc, or the high byte
    size = np.concatenate(([0], np.cumsum(_READING.itemsize - (~wide).astype(np.int64) - fix)))
    return flat[keep].tobytes(), [0, *size[ends].tolist()]


def _array_head(n: int) -> bytes:
    if n < 16:
        return bytes((0x90 | n,))
    if n > MAX_ITEMS:  # no receiver takes it: Observation.from_bytes would refuse it
        raise ValueError(f"{n} readings in one observation > {MAX_ITEMS}")
    return b"\xdc" + n.to_bytes(2, "big")


def encode(
    seqs: Sequence[int],
    *,
    tick: int,
    time_s: float,
    poses: np.ndarray,
    counts: Sequence[int],
    readings: tuple[bytes, list[int]],
) -> list[bytes]:
    """Robot k's Observation (no obstacles): seqs[k], this tick and time, its
    own pose poses[k] (x, y, theta), its counts[k] readings, the next of
    ``readings`` (:func:`readings_bytes`)."""
    common = msgpack.packb(tick) + msgpack.packb(float(time_s))
    pose = np.asarray(poses, dtype=float).reshape(-1, 3)
    rows = np.empty(len(pose), _POSE)
    rows["array"] = 0x93
    rows["f_x"] = rows["f_y"] = rows["f_t"] = 0xCB
    rows["x"], rows["y"], rows["t"] = pose[:, 0], pose[:, 1], pose[:, 2]
    pose_bytes, size = rows.tobytes(), _POSE.itemsize
    buf, starts = readings
    pack = msgpack.packb
    return [
        b"".join(
            (
                _HEAD,
                pack(seq),
                common,
                pose_bytes[size * k : size * (k + 1)],
                _array_head(m),
                buf[starts[k] : starts[k + 1]],
                b"\x90",
            )
        )
        for k, (seq, m) in enumerate(zip(seqs, counts, strict=True))
    ]


def observation_payloads(eng: WorldEngine, observed: list[int], seqs: Mapping[int, int]) -> list[tuple[int, bytes]]:
    """Each robot of ``observed``'s Observation of this tick, numbered ``seqs``,
    as bytes, in order: the followers whose camera no fault touches encoded
    at once, the others (the leader, a faulty camera) one by one."""
    tick, t = eng.tick, eng.time_s
    fast, seen, others = eng.observation_batch(observed)
    payloads = encode(
        [seqs[rid] for rid in fast],
        tick=tick,
        time_s=t,
        poses=pose_array({rid: eng.robots[rid].pose for rid in fast}, fast),
        counts=seen.counts,
        readings=readings_bytes(seen.ids, seen.rho, seen.phi, seen.beta, seen.counts),
    )
    encoded = dict(zip(fast, payloads, strict=True))
    return [
        (rid, encoded[rid] if rid in encoded else observation(seqs[rid], tick, t, others[rid]).to_bytes())
        for rid in observed
    ]


def observation(seq: int, tick: int, time_s: float, observed: Observed) -> Observation:
    """The Observation of one robot's (pose, readings, obstacles)."""
    pose, readings, obstacles = observed
    return Observation(
        sender=WORLD_ID,
        seq=seq,
        tick=tick,
        time_s=time_s,
        pose=pose,
        readings=tuple(readings),
        obstacles=tuple(obstacles),
    )
