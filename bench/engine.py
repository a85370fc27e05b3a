"""Ticks per second of fig11_obstacles stepped in one process
(``formation_swarm.Engine``) beside the same run distributed in lockstep
(``swarm run --mode lockstep``: a world, three agents and a logger over
Zenoh), measured alternately in one invocation so their ratio holds on a
loaded machine. Both runs are the whole scenario with the paper's controller;
the engine's rate is its ticks over the wall time of its ``step`` calls, the
distributed run's is the world's loop (summary.json ``ticks_per_s``). The two
runs' trajectory digests are printed: they are one run.

    python bench/engine.py [--repeat 3] [--seed 1]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formation_swarm import Engine, Launch  # noqa: E402

SCENARIO = ROOT / "scenarios" / "fig11_obstacles.toml"


def engine_rate(seed: int) -> tuple[float, int, str]:
    eng = Engine(SCENARIO, seed=seed)
    t0 = time.perf_counter()
    while eng.step():
        pass
    wall_s = time.perf_counter() - t0
    res = eng.run()
    return res.summary["ticks"] / wall_s, res.summary["ticks"], res.trajectory_digest


def lockstep_rate(seed: int) -> tuple[float, int, str]:
    with (
        tempfile.TemporaryDirectory() as tmp,
        Launch(SCENARIO, out=Path(tmp) / "run", mode="lockstep", seed=seed, progress=lambda _l: None) as launch,
    ):
        res = launch.wait(timeout_s=600)
        if res.exit_code != 0:
            raise SystemExit(f"lockstep run failed: exit {res.exit_code}")
        return float(res.summary["ticks_per_s"]), res.summary["ticks"], res.summary["trajectory_digest"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3, metavar="N", help="rounds, each measuring both (default 3)")
    ap.add_argument("--seed", type=int, default=1, help="the runs' seed (default 1)")
    args = ap.parse_args()
    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    eng, dist = [], []
    for i in range(args.repeat):
        e_rate, e_ticks, e_digest = engine_rate(args.seed)
        d_rate, d_ticks, d_digest = lockstep_rate(args.seed)
        eng.append(e_rate)
        dist.append(d_rate)
        print(
            f"round {i + 1}/{args.repeat}: engine {e_rate:7.0f} ticks/s ({e_ticks} ticks, digest {e_digest})   "
            f"distributed lockstep {d_rate:7.0f} ticks/s ({d_ticks} ticks, digest {d_digest})",
            flush=True,
        )
    e_med, d_med = statistics.median(eng), statistics.median(dist)
    print(
        f"median of {args.repeat}: engine {e_med:.0f} ticks/s, distributed lockstep {d_med:.0f} ticks/s, "
        f"ratio {e_med / d_med:.2f}; load average {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main()
