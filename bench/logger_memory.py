"""The logger over a long run: its resident memory sampled every 10 s, and
what the run wrote per robot and minute.

N robots in a line on a straight path (``bench/scale.py --straight
--lookahead-m 1``'s run), in real time, the logger on. Prints each sample
(s since launch, the logger's RSS in MB), the growth after the first minute
(MB, and its slope in MB per minute, a least-squares line), and the sizes of
recording.rrd, wire.mcap and summary.json, the first two in MB per robot
and minute of sim time.

    python bench/logger_memory.py [--robots 50] [--minutes 20] [--record-every 1] [--agents-per-process 1]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formation_swarm.launch.launcher import Launch  # noqa: E402

SCENARIO = ROOT / "scenarios" / "fig11_obstacles.toml"
STRAIGHT = [[0.0, 0.0], [0.0, 100000.0]]
SAMPLE_S = 10.0


def rss_mb(pid: int) -> float:
    """A process's resident set size, MB (NaN when it is gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float("nan")


def slope_per_min(samples: list[tuple[float, float]]) -> float:
    """Least-squares slope of (s, MB) samples, MB per minute."""
    n = len(samples)
    if n < 2:
        return float("nan")
    mt = sum(t for t, _ in samples) / n
    mv = sum(v for _, v in samples) / n
    den = sum((t - mt) ** 2 for t, _ in samples)
    return 60.0 * sum((t - mt) * (v - mv) for t, v in samples) / den if den else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, default=50)
    ap.add_argument("--minutes", type=float, default=20.0, help="sim minutes, in real time (default 20)")
    ap.add_argument("--record-every", type=int, default=1, help="run.record_every (default 1: every tick)")
    ap.add_argument("--agents-per-process", type=int, default=1, help="run.agents_per_process (default 1)")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}", flush=True)
    overrides = {
        "run.robots": args.robots,
        "leader.formation": "line",
        "leader.waypoints": STRAIGHT,
        "run.duration_s": 60.0 * args.minutes,
        "controller.lookahead_m": 1.0,
        "run.record_every": args.record_every,
        "run.agents_per_process": args.agents_per_process,
    }
    samples: list[tuple[float, float]] = []
    with (
        tempfile.TemporaryDirectory() as tmp,
        Launch(
            SCENARIO, out=Path(tmp) / "run", mode="realtime", overrides=overrides, progress=lambda _line: None
        ) as launch,
    ):
        t0 = time.monotonic()
        if not launch.wait_until(lambda: launch.sim_time() >= 0.0, timeout_s=300.0):
            raise SystemExit(f"no first tick within 300 s ({launch.run_dir})")
        pid = launch.pids()["logger"]
        next_s = 0.0
        while launch.sim_time() < 60.0 * args.minutes - SAMPLE_S:
            launch.wait_until(lambda due=next_s: time.monotonic() - t0 >= due, timeout_s=SAMPLE_S + 1.0)
            rss = rss_mb(pid)
            samples.append((time.monotonic() - t0, rss))
            print(f"  {samples[-1][0]:7.1f} s  logger RSS {rss:7.1f} MB  sim {launch.sim_time():7.1f} s", flush=True)
            next_s += SAMPLE_S
        res = launch.wait(timeout_s=600.0)
        run = res.run_dir
        sizes = {name: (run / name).stat().st_size / 1e6 for name in ("recording.rrd", "wire.mcap", "summary.json")}
        sim_min = float(res.summary.get("ticks") or 0) * 0.05 / 60.0
    after = [(t, v) for t, v in samples if t >= samples[0][0] + 60.0 and v == v]
    grew = after[-1][1] - after[0][1] if after else float("nan")
    print(
        f"{args.robots} robots, {sim_min:.1f} sim min, record_every {args.record_every}: logger RSS "
        f"{after[0][1] if after else float('nan'):.1f} MB after the first minute, {grew:+.1f} MB since, "
        f"slope {slope_per_min(after):+.2f} MB/min"
    )
    per = args.robots * max(sim_min, 1e-9)
    print(
        f"recording.rrd {sizes['recording.rrd']:.1f} MB ({sizes['recording.rrd'] / per:.3f} MB per robot-minute), "
        f"wire.mcap {sizes['wire.mcap']:.1f} MB ({sizes['wire.mcap'] / per:.3f}), "
        f"summary.json {1e3 * sizes['summary.json']:.0f} kB; load average {os.getloadavg()[0]:.2f}"
    )


if __name__ == "__main__":
    main()
