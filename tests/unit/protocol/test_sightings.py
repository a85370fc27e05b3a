"""Every robot's observations of a tick on one key for the ROS 2 bridge:
packed into payloads under the wire's limit, and taken apart distrustfully."""

from __future__ import annotations

import msgpack

from formation_swarm.protocol import acl, sightings
from formation_swarm.protocol.codec import MAX_PAYLOAD_BYTES, Rejections
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import WORLD_ID, Observation


def observation(rid: int, tick: int = 7, seen: int = 12) -> bytes:
    readings = tuple((1 + (rid + j) % 900, 1.0 + j, 0.1 * j, -0.2) for j in range(seen))
    return Observation(
        sender=WORLD_ID,
        seq=tick + 1,
        tick=tick,
        time_s=tick * 0.05,
        pose=(float(rid), 0.0, 0.0),
        readings=readings,
        obstacles=(),
    ).to_bytes()


def test_a_tick_of_300_robots_goes_in_payloads_under_the_limit_in_order() -> None:
    encoded = [(rid, observation(rid)) for rid in range(1, 301)]
    payloads = sightings.pack(encoded)
    assert len(payloads) > 1
    assert max(map(len, payloads)) <= MAX_PAYLOAD_BYTES
    rej = Rejections()
    out = [pair for p in payloads for pair in sightings.unpack(p, rej)]
    assert rej.total == 0
    assert [rid for rid, _ in out] == list(range(1, 301))
    assert [o.to_bytes() for _, o in out] == [b for _, b in encoded]
    assert out[41][1].readings == Observation.from_bytes(encoded[41][1]).readings


def test_what_is_not_sightings_is_counted_by_reason_and_the_good_pairs_kept() -> None:
    rej = Rejections()
    good = observation(2)
    assert sightings.unpack(b"\xc1", rej) == []
    assert sightings.unpack(msgpack.packb([100, 1, []]), rej) == []  # a batch, not sightings
    assert sightings.unpack(msgpack.packb([sightings.SIGHTINGS_TAG, 9, []]), rej) == []
    assert sightings.unpack(b"\x00" * (MAX_PAYLOAD_BYTES + 1), rej) == []
    mixed = [[2, good], [0, good], ["3", good], [4, b"junk"], [5], [6, observation(6)[:-3]]]
    out = sightings.unpack(msgpack.packb([sightings.SIGHTINGS_TAG, 1, mixed], use_bin_type=True), rej)
    assert [rid for rid, _ in out] == [2]
    assert dict(rej.by_reason) == {
        "not msgpack": 3,  # b"\xc1", junk, a cut observation
        "wrong message type": 1,
        "unknown version": 1,
        "oversized": 1,
        "out of range": 1,  # robot 0
        "wrong type": 2,  # a string id, a pair of one
    }


def test_only_a_run_with_a_bridge_lets_the_world_put_sightings_and_only_the_bridge_hears_them() -> None:
    k = Keys("r1")
    plain = acl.grants("r1", (1, 2, 3), 1)
    assert k.sightings not in plain["world"].publish
    ros = acl.grants("r1", (1, 2, 3), 1, ros2=acl.RosAccess(domain_id=0, namespace="", robots=(3,), login=True))
    assert k.sightings in ros["world"].publish
    hearers = [user for user, g in ros.items() if k.sightings in g.subscribe]
    assert hearers == [acl.BRIDGE]
