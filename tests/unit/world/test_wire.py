"""The world's observations encoded all at once (world.wire) are, byte for
byte, what Observation.to_bytes() gives for each: the receivers' format and
checks are untouched."""

from __future__ import annotations

import time

import numpy as np
import pytest

from formation_swarm.protocol.messages import Observation
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.tick import WorldTick
from formation_swarm.world.wire import encode, readings_bytes

IDS = [1, 5, 127, 128, 200, 255, 256, 300, 9999, 10000]  # each width msgpack gives an integer


def test_the_bytes_are_msgpacks_for_every_width_of_id_and_count() -> None:
    gen = np.random.default_rng(1)
    messages = 0
    for trial in range(300):
        k = int(gen.integers(1, 8))
        counts = (gen.integers(0, 40, k) * (gen.random(k) < 0.7)).tolist()
        total = sum(counts)
        ids = [gen.choice(IDS, total), gen.integers(1, 10001, total), gen.integers(1, 100, total)][trial % 3]
        rho, phi, beta = gen.normal(size=(3, total)) * gen.choice([1.0, 1e-300, 1e300])
        poses, seqs = gen.normal(size=(k, 3)), gen.integers(0, 2**40, k).tolist()
        tick, t = int(gen.integers(0, 2**33)), float(gen.normal())
        got = encode(
            seqs, tick=tick, time_s=t, poses=poses, counts=counts, readings=readings_bytes(ids, rho, phi, beta, counts)
        )
        at = 0
        for q, m in enumerate(counts):
            readings = tuple((int(ids[r]), float(rho[r]), float(phi[r]), float(beta[r])) for r in range(at, at + m))
            at += m
            want = Observation(
                sender=0,
                seq=seqs[q],
                tick=tick,
                time_s=t,
                pose=tuple(poses[q].tolist()),
                readings=readings,
                obstacles=(),
            )
            assert got[q] == want.to_bytes()
            assert Observation.from_bytes(got[q]) == want
            messages += 1
    assert messages > 1000


def test_an_id_no_message_carries_is_refused() -> None:
    with pytest.raises(ValueError, match="robot id"):
        readings_bytes(np.array([70000]), np.zeros(1), np.zeros(1), np.zeros(1), [1])


def test_a_tick_encoded_at_once_is_the_observations_one_by_one() -> None:
    """100 robots of ids 200-299 (of two and three bytes), faulty cameras among them
    (encoded one by one), the leader's obstacles: the same payloads, in the
    same order, the same counts, on every tick."""
    sc = scenario_mod.load(
        scenario_files.resolve("fig11_obstacles"),
        {"run.robots": 100, "leader.id": 200, "leader.formation": "line", "controller.lookahead_m": 1.0},
        faults=["outliers 204,207@0s for=2s p=0.5", "blackout 209@0.5s for=1s"],
    )
    worlds = [WorldTick(sc, 3, lockstep=True, wall_s=time.monotonic) for _ in range(2)]
    code = sc.code_of(sc.leader.formation)
    sent = 0
    for _ in range(20):
        one_by_one = [(rid, obs.to_bytes()) for rid, obs in worlds[0].observations()]
        at_once = worlds[1].encoded_observations()
        assert at_once == one_by_one
        sent += len(at_once)
        for world in worlds:
            for rid in sc.robots:
                world.engine.set_command(rid, 0.9, 1.0 if rid % 3 else 0.8, code, world.engine.time_s)
            world.close()
            world.step()
    a, b = (w.engine.metrics.followers for w in worlds)
    assert [(m.frames, m.seen_ticks) for m in a.values()] == [(m.frames, m.seen_ticks) for m in b.values()]
    assert worlds[0].counts == worlds[1].counts
    assert sum(m.seen_ticks for m in a.values()) > 0.9 * 99 * 20
    assert sent == 100 * 20
