"""CPU time of the world's work per tick, without Zenoh, on the world process's
own path (world.tick.WorldTick, lockstep): every robot's observation
(cameras) and its encoding; the ground truth (taken, its digests fed, its
message encoded); the step (kinematics); the metrics (record: formation
errors, contacts, digest); and apart, the answers (each robot's Command
decoded and judged), which the world's figure of merit has left out so far.
N robots in a line on fig11's path, each robot driven straight ahead.

    python bench/world_tick.py [--robots 10 100 200 500 1000] [--ticks 100]

Beyond the scenario's limit of robots (spec.keys.MAX_ROBOTS: the ground truth
must fit one message) the line is made longer here, for the world alone.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formation_swarm.protocol.messages import Command  # noqa: E402
from formation_swarm.spec import files as scenario_files  # noqa: E402
from formation_swarm.spec import scenario as scenario_mod  # noqa: E402
from formation_swarm.spec.formations import parse_formations  # noqa: E402
from formation_swarm.spec.keys import MAX_ROBOTS  # noqa: E402
from formation_swarm.world.tick import WorldTick  # noqa: E402

STAGES = ("observe", "truth", "step", "record", "answers")


def line_of(n: int) -> scenario_mod.Scenario:
    """fig11 with ``n`` robots in a line (each following the one ahead)."""
    with warnings.catch_warnings():  # the long chain's steering warning: each robot is driven straight here
        warnings.simplefilter("ignore")
        sc = scenario_mod.load(
            scenario_files.resolve("fig11_obstacles"),
            {"run.robots": min(n, MAX_ROBOTS), "leader.formation": "line"},
        )
    if n <= MAX_ROBOTS:
        return sc
    lead = sc.leader.robot_id
    robots = tuple(range(lead, lead + n))
    ld = {"id": lead, "formation": sc.leader.formation, "avoid_formation": ""}
    return dataclasses.replace(sc, robots=robots, formations=parse_formations(sc.raw["formations"], robots, ld))


def per_tick(n: int, ticks: int) -> dict[str, float]:
    """Microseconds of CPU per tick, by stage."""
    sc = line_of(n)
    world = WorldTick(sc, 0, lockstep=True, wall_s=time.monotonic)
    eng = world.engine
    code = sc.code_of(sc.leader.formation)
    spent = dict.fromkeys(STAGES, 0.0)
    for k in range(ticks):
        straight = {"left_mps": 1.0, "right_mps": 1.0, "formation": code, "done": False}
        # The agents' work, not timed.
        payloads = [(rid, Command(sender=rid, seq=k + 1, tick=eng.tick, **straight).to_bytes()) for rid in sc.robots]
        world.start(time.monotonic())
        t0 = time.process_time()
        if hasattr(world, "encoded_observations"):
            world.encoded_observations()
        else:  # the code before it: one Observation at a time
            [obs.to_bytes() for _, obs in world.observations()]
        t1 = time.process_time()
        truth = world.truth()  # the last tick's (taken at its close)
        if truth is not None:
            truth.to_bytes()
        t2 = time.process_time()
        for rid, payload in payloads:
            world.receive(rid, payload)
        t3 = time.process_time()
        world.close()  # this tick's ground truth taken, the robots' digests fed
        t4 = time.process_time()
        world.step()
        t5 = time.process_time()
        world.record()
        t6 = time.process_time()
        spent["observe"] += t1 - t0
        spent["truth"] += (t2 - t1) + (t4 - t3)
        spent["answers"] += t3 - t2
        spent["step"] += t5 - t4
        spent["record"] += t6 - t5
    return {k: 1e6 * v / ticks for k, v in spent.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, nargs="+", default=[10, 100, 200, 500, 1000])
    ap.add_argument("--ticks", type=int, default=100)
    args = ap.parse_args()
    if min(args.robots) < 2 or args.ticks < 1:
        ap.error("--robots: at least 2 each; --ticks: at least 1")
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    for n in args.robots:
        r = per_tick(n, args.ticks)
        parts = ", ".join(f"{k} {v:6.0f}" for k, v in r.items() if k != "answers")
        total = sum(v for k, v in r.items() if k != "answers")
        print(
            f"{n:5d} robots: {total:8.0f} us of CPU per tick, {total / n:5.1f} per robot ({parts}); "
            f"answers {r['answers']:6.0f} more",
            flush=True,
        )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
