"""CPU time of the world's work per tick, without Zenoh: every robot's
observation (cameras), its encoding, the truth message, the step
(kinematics) and the metrics (record: formation errors, contacts, digest),
for N robots in a line on fig11's path, each robot driven straight ahead.

    python bench/world_tick.py [--robots 10 50 100 200] [--ticks 200]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formation_swarm.protocol.messages import WORLD_ID, Observation, Truth  # noqa: E402
from formation_swarm.spec import files as scenario_files  # noqa: E402
from formation_swarm.spec import scenario as scenario_mod  # noqa: E402
from formation_swarm.world.engine import WorldEngine  # noqa: E402


def per_tick(n: int, ticks: int) -> dict[str, float]:
    sc = scenario_mod.load(scenario_files.resolve("fig11_obstacles"), {"run.robots": n, "leader.formation": "line"})
    eng = WorldEngine(sc, 0)
    ids = sorted(eng.robots)
    spent = {"observe": 0.0, "encode": 0.0, "step": 0.0, "record": 0.0}
    for _ in range(ticks):
        t0 = time.process_time()
        obs = eng.observations(ids) if hasattr(eng, "observations") else {r: eng.observation(r) for r in ids}
        t1 = time.process_time()
        for pose, readings, obstacles in obs.values():
            Observation(
                sender=WORLD_ID,
                seq=eng.tick + 1,
                tick=eng.tick,
                time_s=eng.time_s,
                pose=pose,
                readings=tuple(readings),
                obstacles=tuple(obstacles),
            ).to_bytes()
        robots = tuple((rid, *r.pose, r.alive) for rid, r in eng.robots.items())
        targets = tuple((rid, *eng.true_target(rid)) for rid in sc.follower_ids)
        Truth(sender=0, seq=eng.tick + 1, tick=eng.tick, time_s=eng.time_s, robots=robots, targets=targets).to_bytes()
        t2 = time.process_time()
        for rid in ids:
            eng.set_command(rid, 1.0, 1.0, 0, eng.time_s)
        eng.step(eng.time_s)
        t3 = time.process_time()
        eng.record()
        t4 = time.process_time()
        for k, a, b in (("observe", t0, t1), ("encode", t1, t2), ("step", t2, t3), ("record", t3, t4)):
            spent[k] += b - a
    return {k: 1e6 * v / ticks for k, v in spent.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, nargs="+", default=[10, 50, 100, 200])
    ap.add_argument("--ticks", type=int, default=200)
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    for n in args.robots:
        r = per_tick(n, args.ticks)
        parts = ", ".join(f"{k} {v:7.0f}" for k, v in r.items())
        print(f"{n:4d} robots: {sum(r.values()):8.0f} us of CPU per tick ({parts})", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
