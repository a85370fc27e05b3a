"""How a run scales with its number of robots: N robots in a line on fig11's
path (``run.robots=N``, ``leader.formation=line``: each robot follows the
one ahead of it), the logger on, in real time and in lockstep.

Per N and mode it prints:

- ``start``: wall seconds from the launch to the first tick (every process
  forked, connected and ready). The spawner's server, which imports the
  roles' modules once, starts with the first run of this script and serves
  the later ones: the first row's start includes it (marked "cold"), the
  others' do not; ``swarm run`` always starts cold;
- real time: the ticks late by more than half a period, and the 99th
  percentile and the largest lateness of a tick (ms); and ``skipped``, the
  share of the followers' observations never answered because a newer one
  had arrived by the time the agent got to them (an agent that keeps up
  skips none), and the same share of the leader's; and the world's scheduling class (real-time, or NORMAL
  where the machine refused it: see ``swarm world --rt-priority``);
- lockstep: the world's ticks per wall second;
- CPU per tick, in microseconds: of an agent (the mean and the largest over the
  followers, from each agent's CPU time over its loop, ``loop_cpu_s``, divided
  by the observations it answered), of the world and of the logger (and,
  of the logger's loop thread, what its sends to Rerun took and what taking
  the messages apart and checking them took), and the ticks it recorded;
- the collisions between robots, and the closest two robots came (m);
- PSS per robot's agent (MB, shared pages counted once; a process of K robots'
  agents counts 1/K), sampled a second into the run.

``--agents-per-process K ...`` runs each N and mode once per K
(``run.agents_per_process``: K robots' agents in one process, each with its own
session); the agents' CPU of a shared process is split evenly among its robots.

The machine's load average is printed before and after: other work on the
machine shows in every figure.

    python bench/scale.py [--robots N ...] [--modes realtime lockstep]
                          [--duration 20] [--lockstep-duration 10] [--no-logger]
                          [--straight] [--lookahead-m 1] [--agents-per-process 1 10]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formation_swarm.launch.launcher import Launch  # noqa: E402
from formation_swarm.runtime.cliargs import integer, non_negative, seconds  # noqa: E402
from formation_swarm.spec.keys import MAX_ROBOTS  # noqa: E402

SCENARIO = ROOT / "scenarios" / "fig11_obstacles.toml"
STRAIGHT = [[0.0, 0.0], [0.0, 1000.0]]  # --straight: a path that never ends within the duration


def pss_mb(pid: int) -> float:
    """A process's proportional set size, MB (NaN when it is gone)."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float("nan")


_SAID: set[str] = set()


def _warnings_once(line: str) -> None:
    """The launcher's console: only the scenario's warnings, each once (they
    name the robots, so each N has its own)."""
    if line.startswith("[swarm] warning") and line not in _SAID:
        _SAID.add(line)
        print(f"  {line}", flush=True)


def one(
    n: int, mode: str, duration_s: float, logger: bool, straight: bool, lookahead_m: float, tmp: Path, k: int = 1
) -> dict[str, Any]:
    overrides: dict[str, Any] = {
        "run.agents_per_process": k,
        "run.robots": n,
        "leader.formation": "line",
        "run.duration_s": duration_s,
        "controller.lookahead_m": lookahead_m,
    }
    if straight:
        overrides["leader.waypoints"] = STRAIGHT
    t0 = time.monotonic()
    with Launch(
        SCENARIO,
        mode=mode,
        out=tmp / f"{mode}-{n}-{time.time_ns()}",
        overrides=overrides,
        logger=logger,
        progress=_warnings_once,
    ) as launch:
        if not launch.wait_until(lambda: launch.sim_time() >= 0.0, timeout_s=900.0):
            raise SystemExit(f"{n} robots, {mode}: no first tick within 900 s ({launch.run_dir})")
        start_s = time.monotonic() - t0
        launch.wait_until(lambda: launch.sim_time() >= min(1.0, 0.5 * duration_s), timeout_s=60.0)
        pss = [pss_mb(pid) / k for name, pid in launch.pids().items() if name.startswith("agent")]
        res = launch.wait(timeout_s=max(600.0, 20 * duration_s))
    s = res.summary
    parts = s.get("parts", {})
    world = parts.get("world", {})
    followers = [p for name, p in parts.items() if name.startswith("agent-") and p.get("role") == "follower"]
    leader = next((p for name, p in parts.items() if name.startswith("agent-") and p.get("role") == "leader"), {})
    per_tick = [1e6 * p["loop_cpu_s"] / p["answered"] for p in followers if p.get("answered")]
    ticks = max(1, int(s.get("ticks") or 0))
    return {
        "k": k,
        "exit": res.exit_code,
        "start_s": start_s,
        "ticks": ticks,
        "late": s.get("late_ticks"),
        "scheduling": s.get("world_scheduling") or "",
        "p99_ms": 1e3 * (world.get("p99_tick_lateness_s") or float("nan")),
        "max_ms": 1e3 * (s.get("max_tick_lateness_s") or 0.0),
        "ticks_per_s": s.get("ticks_per_s"),
        "agent_us": statistics.mean(per_tick) if per_tick else float("nan"),
        "agent_max_us": max(per_tick, default=float("nan")),
        "world_us": 1e6 * world.get("loop_cpu_s", float("nan")) / ticks,
        "logger_us": 1e6 * parts.get("logger", {}).get("loop_cpu_s", float("nan")) / ticks,
        "logger_send_us": 1e6 * parts.get("logger", {}).get("send_cpu_s", float("nan")) / ticks,
        "logger_drain_us": 1e6 * parts.get("logger", {}).get("drain_cpu_s", float("nan")) / ticks,
        "pss_mb": statistics.mean(p for p in pss if p == p) if any(p == p for p in pss) else float("nan"),
        "misses": s.get("lockstep_misses"),
        "recorded": parts.get("logger", {}).get("messages", {}).get("truth"),
        # Observations an agent never answered: a newer one had come by the time it got to them.
        "skipped": sum(p.get("superseded", 0) for p in followers),
        "observed": sum(p.get("superseded", 0) + p.get("answered", 0) for p in followers),
        "collisions": s.get("collisions"),
        "closest_m": s.get("min_distance_m"),
        "leader_skipped": leader.get("superseded", 0),
        "leader_observed": leader.get("superseded", 0) + leader.get("answered", 0),
    }


def line(n: int, mode: str, r: dict[str, Any], cold: bool = False) -> str:
    head = f"{n:4d} robots K={r['k']:<3d} {mode:8s} start {r['start_s']:6.2f} s{' (cold)' if cold else '       '}"
    if mode == "realtime":
        rt = "real-time" if r["scheduling"].startswith("real-time") else "NORMAL class"
        timing = (
            f"late {r['late']:4d}/{r['ticks']:<5d} p99 {r['p99_ms']:7.1f} ms max {r['max_ms']:7.1f} ms "
            f"skipped {100 * r['skipped'] / max(1, r['observed']):4.1f}% "
            f"(leader {100 * r['leader_skipped'] / max(1, r['leader_observed']):.1f}%) "
            f"(world {rt})"
        )
    else:
        timing = f"{r['ticks_per_s']:7.1f} ticks/s ({r['ticks']} ticks, misses {r['misses']})"
    cpu = (
        f"CPU/tick: agent {r['agent_us']:6.0f} us (max {r['agent_max_us']:6.0f}), world {r['world_us']:7.0f} us, "
        f"logger {r['logger_us']:6.0f} us (send {r['logger_send_us']:.0f}, take {r['logger_drain_us']:.0f}; "
        f"recorded {r['recorded']} ticks)"
    )
    bad = "" if r["exit"] == 0 else f"  EXIT {r['exit']}"
    closest = "" if r["closest_m"] is None else f" (closest {r['closest_m']:.2f} m)"
    return f"{head}  {timing}  collisions {r['collisions']}{closest}  {cpu}  PSS/agent {r['pss_mb']:5.1f} MB{bad}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--robots",
        type=integer(2, MAX_ROBOTS),
        nargs="+",
        default=[10, 50, 100],
        metavar="N",
        help="the swarm sizes, each run in every mode (default 10 50 100)",
    )
    ap.add_argument(
        "--modes",
        nargs="+",
        choices=("realtime", "lockstep"),
        default=["realtime", "lockstep"],
        help="real time, lockstep or both (default both)",
    )
    ap.add_argument("--duration", type=seconds(), default=20.0, help="sim seconds of a real-time run (default 20)")
    ap.add_argument(
        "--lockstep-duration", type=seconds(), default=10.0, help="sim seconds of a lockstep run (default 10)"
    )
    ap.add_argument("--no-logger", action="store_true", help="without the logger")
    ap.add_argument("--straight", action="store_true", help="a straight path, for durations beyond fig11's 56 s")
    ap.add_argument(
        "--lookahead-m",
        type=non_negative,
        default=0.0,
        help="the followers' steering look-ahead, controller.lookahead_m (default 0, the paper's steering; "
        "1 keeps the heading swings from growing down the line: docs/paper.md)",
    )
    ap.add_argument(
        "--agents-per-process",
        type=integer(1, MAX_ROBOTS),
        nargs="+",
        default=[1],
        metavar="K",
        help="robots' agents per process, each K a run of its own (default 1: a process per robot)",
    )
    args = ap.parse_args()
    print(
        f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; "
        f"followers' look-ahead {args.lookahead_m:g} m",
        flush=True,
    )
    with tempfile.TemporaryDirectory() as tmp:
        first = (args.robots[0], args.modes[0], args.agents_per_process[0])
        for n in args.robots:
            for mode in args.modes:
                duration = args.duration if mode == "realtime" else args.lockstep_duration
                for k in args.agents_per_process:
                    r = one(n, mode, duration, not args.no_logger, args.straight, args.lookahead_m, Path(tmp), k)
                    print(
                        line(n, mode, r, cold=(n, mode, k) == first),
                        f"load {os.getloadavg()[0]:.2f}",
                        flush=True,
                    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
