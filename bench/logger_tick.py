"""CPU time of the logger's work per tick, without Zenoh: N robots in a line
(``run.robots=N``, ``leader.formation=line``) at 20 Hz, a truth batch and
every follower's telemetry batch per tick handed to the logger's loop as it
takes them (decoded and checked), sent to Rerun as the loop does (every
``send_period_s`` of sim time: real time's cadence) into a recording file.

CPU is the process's (all threads, Rerun's writers included), per tick,
after a warm-up of 2 sends. ``--old-root DIR`` runs the same ticks against
another checkout of the code (``git clone . DIR && git -C DIR checkout REV``)
in the same invocation, for a ratio that holds on a loaded machine.

    python bench/logger_tick.py [--robots 50 100 200] [--ticks 400] [--old-root DIR]
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
# The package's folders (pyproject.toml's package-dir): formation_swarm is swarm/.
MAPPED = ("agents", "world", "protocol", "scenarios")


def per_tick(n: int, ticks: int, out: Path) -> dict[str, float]:
    from formation_swarm.nodes.logger.main import Logger
    from formation_swarm.nodes.logger.recorder import Recorder
    from formation_swarm.nodes.logger.recording import open_recording
    from formation_swarm.protocol.keys import Keys
    from formation_swarm.runtime import process as process_mod
    from formation_swarm.spec import files as scenario_files
    from formation_swarm.spec import scenario as scenario_mod

    over = {"run.robots": n, "leader.formation": "line", "run.duration_s": ticks * 0.05 + 60.0}  # past the warm-up
    sc = scenario_mod.load(scenario_files.resolve("fig11_obstacles"), over)
    rec = open_recording("bench", out, sc)
    logger = Logger(None, sc, "bench", Recorder(rec, sc), process_mod.Process("logger", 1.0))  # type: ignore[arg-type]
    keys = Keys("bench")
    per_send = max(1, round(logger.send_period_s / sc.dt_s))
    warm = 2 * per_send
    payloads = [_tick_payloads(sc, k, keys) for k in range(ticks + warm)]  # encoded before the clock starts
    _collector_as_the_logger_sets_it()
    cpu0 = wall0 = 0.0
    for k, tick in enumerate(payloads):
        if k == warm:
            cpu0, wall0 = time.process_time(), time.perf_counter()
        for key, payload in tick:
            logger._handle(key, payload)
        if (k + 1) % per_send == 0:
            logger.recorder.send()
            logger.recorder.flush(timeout_s=1.0)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    logger.recorder.send(final=True)
    rec.close()
    return {"cpu_ms": 1e3 * cpu / ticks, "wall_ms": 1e3 * wall / ticks, "mb": out.stat().st_size / 1e6}


def _collector_as_the_logger_sets_it() -> None:
    """What the logger's loop does to Python's collector once started (gc.freeze before
    runtime.memory.steady_collector)."""
    from formation_swarm.runtime import memory

    getattr(memory, "steady_collector", gc.freeze)()


def _tick_payloads(sc: Any, k: int, keys: Any) -> list[tuple[str, bytes]]:
    """Tick ``k``'s batches as the logger takes them: the world's truth, then each follower's telemetry."""
    from formation_swarm.protocol.batch import pack_batch
    from formation_swarm.protocol.messages import WORLD_ID, Telemetry, Truth

    t, ids, followers = k * sc.dt_s, sorted(sc.robots), set(sc.follower_ids)
    robots = tuple((r, 0.3 * i, 0.2 * t - 0.5 * i, math.pi / 2, True) for i, r in enumerate(ids))
    targets = tuple((r, 0.3 * i + 0.01, 0.2 * t - 0.5 * i) for i, r in enumerate(ids) if r in followers)
    out = [
        (
            keys.truth,
            pack_batch(
                [Truth(sender=WORLD_ID, seq=k + 1, tick=k, time_s=t, robots=robots, targets=targets).to_bytes()]
            ),
        )
    ]
    for i, r in enumerate(sc.follower_ids):
        w = 0.1 * math.sin(0.3 * t + i)
        tel = Telemetry(
            sender=r, seq=k + 1, tick=k, time_s=t, reference=r - 1, formation=1,
            measured=(0.01 + w, -0.5), estimate=(0.01, -0.5 + w), target_cov=(0.01, 0.0, 0.02),
            rho_m=0.5 + w, alpha_rad=w, vn=0.2 + w, left_mps=0.2, right_mps=0.21,
            steering_to=0, changing=False, obs_dropped=0, formation_dropped=0, rejected=0,
        )  # fmt: skip
        out.append((keys.telemetry(r), pack_batch([tel.to_bytes()])))
    return out


def _farm(old: Path, into: Path) -> Path:
    """An import path where formation_swarm is ``old``'s code (its folders mapped as pyproject.toml maps them)."""
    pkg = into / "formation_swarm"
    pkg.mkdir()
    for entry in (old / "swarm").iterdir():
        (pkg / entry.name).symlink_to(entry)
    for name in MAPPED:
        (pkg / name).symlink_to(old / name)
    return into


def _child(n: int, ticks: int, pythonpath: Path | None) -> dict[str, float]:
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    cmd = [sys.executable, __file__, "--child", str(n), "--ticks", str(ticks)]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1800, check=False)
    if res.returncode != 0:
        raise SystemExit(f"{n} robots: the measuring process failed: {res.stderr.strip().splitlines()[-1:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, nargs="+", default=[50, 100, 200], metavar="N")
    ap.add_argument("--ticks", type=int, default=400, help="ticks measured per N, after the warm-up (default 400)")
    ap.add_argument("--old-root", type=Path, metavar="DIR", help="also measure the code of this checkout")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        with tempfile.TemporaryDirectory() as tmp:
            print(json.dumps(per_tick(args.child, args.ticks, Path(tmp) / "bench.rrd")))
        return
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        old = _farm(args.old_root.resolve(), Path(tmp)) if args.old_root else None
        for n in args.robots:
            for name, path in (("this", None), ("old", old)) if old else (("this", None),):
                r = _child(n, args.ticks, path)
                print(
                    f"{n:4d} robots  {name:4s}  logger CPU {r['cpu_ms']:6.2f} ms/tick  wall {r['wall_ms']:6.2f} ms/tick"
                    f"  file {r['mb']:.2f} MB",
                    flush=True,
                )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
