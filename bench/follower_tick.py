"""A follower's tick without Zenoh: where its CPU goes, part by part.

N robots in a line on fig11's path (``--straight``: a straight path), run in
lockstep in this one process: the world's tick (world.tick.WorldTick)
publishes each robot's encoded observation, and each robot's process code
takes it as its loop does (nodes.agent.main: the inbox's router decodes it for
the role, the role answers, the outbox encodes and publishes the answer to
stand-in publishers, the role prepares its next tick, the stats file and
the flood watch look). The command goes back to the world encoded, the
leader's formation codes to every follower. The followers' parts are timed
with ``perf_counter`` on every tick after the first ``--warmup``:

- ``take``: the inbox (decoding, checks, link layer);
- ``answer``: the role's answer, and within it ``controller`` (its step);
- ``send``: encoding and publishing the command and the telemetry;
- ``prepare``: the EKF's prediction for the next tick;
- ``after``: the stats file's and the flood watch's looks.

It prints the median over ``--repeat`` rounds of the mean per follower tick
(us), the world's tick (us, all robots), the world's trajectory digest and
a digest of every message the robots sent (telemetry taken out of its
batches): neither may change when only the cost changes. ``--profile`` prints
cProfile's top entries of the followers' parts instead.

    python bench/follower_tick.py [--robots 10] [--ticks 400] [--repeat 5] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import gc
import hashlib
import os
import pstats
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formation_swarm.nodes.agent.setup import role_for  # noqa: E402
from formation_swarm.nodes.agent.stats import StatsFile  # noqa: E402
from formation_swarm.nodes.agent.wire import Outbox, Router  # noqa: E402
from formation_swarm.protocol.codec import unpack_batch  # noqa: E402
from formation_swarm.protocol.keys import Keys  # noqa: E402
from formation_swarm.runtime.memory import FloodRelief  # noqa: E402
from formation_swarm.spec import files as scenario_files  # noqa: E402
from formation_swarm.spec import scenario as scenario_mod  # noqa: E402
from formation_swarm.world.tick import WorldTick  # noqa: E402

PARTS = ("take", "answer", "controller", "send", "prepare", "after")
STRAIGHT = [[0.0, 0.0], [0.0, 1000.0]]


class Pub:
    """A stand-in publisher: keeps what is put."""

    def __init__(self) -> None:
        self.sent: list[bytes] = []

    def put(self, payload: bytes) -> None:
        self.sent.append(payload)


class Timed:
    """A controller whose steps are timed."""

    def __init__(self, inner: Any, spent: dict[str, float]) -> None:
        self.inner = inner
        self.spent = spent
        self.prepare = getattr(inner, "prepare", None)

    def step(self, inp: Any) -> Any:
        t0 = time.perf_counter()
        out = self.inner.step(inp)
        self.spent["controller"] += time.perf_counter() - t0
        return out


class Robot:
    """One robot's process code, with stand-in publishers."""

    def __init__(self, sc: Any, rid: int, seed: int, keys: Keys, spent: dict[str, float]) -> None:
        self.role = role_for(sc, rid, seed)
        if hasattr(self.role, "controller"):
            self.role.controller = Timed(self.role.controller, spent)
            self.role._prepare = getattr(self.role.controller, "prepare", None)
        self.router = Router(keys, self.role)
        self.cmd, self.tel, self.code = Pub(), Pub(), Pub()
        self.outbox = Outbox(rid, len(sc.robots), self.cmd, self.tel, self.code)
        self.stats_file = StatsFile(None, len(sc.robots), ())
        self.relief = FloodRelief()
        self.spent = spent

    def wire_telemetry(self, wire: Any) -> None:
        """The telemetry sent since the last call, out of its batches, into ``wire``."""
        for batch in self.tel.sent:
            for payload in unpack_batch(batch):
                wire.update(payload)
        self.tel.sent.clear()

    def serve(self, messages: list[tuple[str, bytes]], timed: bool) -> None:
        """One pass of the agent's loop (nodes.agent.node.Agent._serve)."""
        spent, clock = self.spent, time.perf_counter
        t0 = clock()
        for key, payload in messages:
            self.router.take(key, payload)
        t1 = clock()
        answer = self.role.answer()
        t2 = clock()
        if answer is not None:
            self.outbox.send(answer)
        t3 = clock()
        if answer is not None:
            self.role.prepare()
        t4 = clock()
        self.role.notes.clear()
        self.stats_file.after(None if answer is None else answer.command.tick, dict)
        self.relief.check(self.role.rejections.total)
        t5 = clock()
        if timed:
            for part, a, b in (("take", t0, t1), ("answer", t1, t2), ("send", t2, t3), ("prepare", t3, t4)):
                spent[part] += b - a
            spent["after"] += t5 - t4
            spent["ticks"] += 1


def one_run(args: argparse.Namespace, profile: cProfile.Profile | None) -> dict[str, Any]:
    overrides: dict[str, Any] = {
        "run.robots": args.robots,
        "leader.formation": "line",
        "controller.lookahead_m": args.lookahead_m,
    }
    if args.straight:
        overrides["leader.waypoints"] = STRAIGHT
    sc = scenario_mod.load(scenario_files.resolve("fig11_obstacles"), overrides)
    seed = sc.seed
    keys = Keys("bench")
    world = WorldTick(sc, seed, lockstep=True, wall_s=lambda: 0.0)
    follower_spent = dict.fromkeys((*PARTS, "ticks"), 0.0)
    leader_spent = dict.fromkeys((*PARTS, "ticks"), 0.0)
    leader_id = sc.leader.robot_id
    robots = {
        rid: Robot(sc, rid, seed, keys, leader_spent if rid == leader_id else follower_spent) for rid in sc.robots
    }
    obs_keys = {rid: keys.obs(rid) for rid in sc.robots}
    codes: list[bytes] = []
    # What each robot sent: commands, telemetry (out of its batches), codes.
    wire = {rid: hashlib.sha256() for rid in sc.robots}
    tel_wire = {rid: hashlib.sha256() for rid in sc.robots}  # apart: batches leave by wall time
    world_s = agents_cpu_s = 0.0
    ticks = 0
    gc.collect()
    while world.running and ticks < args.ticks:
        timed = ticks >= args.warmup
        w0 = time.perf_counter()
        world.start(0.0)
        published = [(rid, obs.to_bytes()) for rid, obs in world.observations()]
        if (truth := world.truth()) is not None:
            truth.to_bytes()
        world.record()
        world_s += (time.perf_counter() - w0) if timed else 0.0
        if profile is not None and timed:
            profile.enable()
        c0 = time.process_time()
        for rid, payload in published:
            r = robots[rid]
            messages = [(keys.codes, c) for c in codes] if rid != leader_id else []
            messages.append((obs_keys[rid], payload))
            r.serve(messages, timed)
        if timed:
            agents_cpu_s += time.process_time() - c0
        if profile is not None and timed:
            profile.disable()
        w0 = time.perf_counter()
        for rid, _ in published:
            r = robots[rid]
            for payload in r.cmd.sent:
                world.receive(rid, payload)
                wire[rid].update(payload)
            r.cmd.sent.clear()
            r.wire_telemetry(tel_wire[rid])
        for payload in robots[leader_id].code.sent:
            wire[leader_id].update(payload)
        codes = robots[leader_id].code.sent[:]
        robots[leader_id].code.sent.clear()
        world.close()
        world.step()
        world_s += (time.perf_counter() - w0) if timed else 0.0
        ticks += 1
    every = hashlib.sha256()
    for rid, r in robots.items():
        r.outbox.tel.flush()
        r.wire_telemetry(tel_wire[rid])
        every.update(wire[rid].digest() + tel_wire[rid].digest())
    n = max(1.0, follower_spent.pop("ticks"))
    measured = max(1, ticks - args.warmup)
    robot_ticks = n + leader_spent["ticks"]
    return {
        "cpu_us": 1e6 * agents_cpu_s / max(1.0, robot_ticks),
        "follower": {k: 1e6 * v / n for k, v in follower_spent.items()},
        "world_us": 1e6 * world_s / measured,
        "ticks": ticks,
        "digest": world.engine.digest(),
        "wire": every.hexdigest(),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, default=10)
    ap.add_argument("--ticks", type=int, default=400)
    ap.add_argument("--warmup", type=int, default=20, help="ticks not timed at the start (default 20)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--straight", action="store_true", help="a straight path instead of fig11's")
    ap.add_argument("--lookahead-m", type=float, default=1.0)
    ap.add_argument("--profile", action="store_true", help="cProfile's top entries of the robots' parts")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; {sys.executable}", flush=True)
    if args.profile:
        prof = cProfile.Profile()
        one_run(args, prof)
        pstats.Stats(prof).sort_stats("tottime").print_stats(40)
        return
    runs = [one_run(args, None) for _ in range(args.repeat)]
    med = {k: statistics.median(r["follower"][k] for r in runs) for k in PARTS}
    total = sum(v for k, v in med.items() if k != "controller")
    parts = ", ".join(f"{k} {med[k]:.1f}" for k in PARTS)
    print(f"{args.robots} robots, {runs[0]['ticks']} ticks, median of {args.repeat}")
    cpu = statistics.median(r["cpu_us"] for r in runs)
    print(f"robot tick: {cpu:.1f} us of CPU (process time, all robots); follower tick by wall clock:")
    print(f"  {total:.1f} us ({parts})")
    print(f"world tick: {statistics.median(r['world_us'] for r in runs):.0f} us")
    print(f"trajectory digest: {runs[0]['digest']}")
    print(f"what the robots sent: {runs[0]['wire']}; load average after {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
