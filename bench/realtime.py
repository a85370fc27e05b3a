"""Real-time run of the three-robot scenario at the scenario's rate (20 Hz):
late ticks (started more than half a period late) and the worst lateness.

    python bench/realtime.py [--duration 53]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formation_swarm.launch.launcher import Launch  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=None, help="sim seconds (default: the scenario's)")
    args = ap.parse_args()
    overrides = {} if args.duration is None else {"run.duration_s": args.duration}
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    with (
        tempfile.TemporaryDirectory() as tmp,
        Launch(
            ROOT / "scenarios" / "fig11_obstacles.toml",
            mode="realtime",
            out=Path(tmp) / "run",
            overrides=overrides,
            progress=lambda _l: None,
        ) as launch,
    ):
        res = launch.wait(timeout_s=600)
    s = res.summary
    rate = 1.0 / launch.sc.dt_s
    late_ms = 1e3 * s["max_tick_lateness_s"]
    print(
        f"real time at {rate:.0f} Hz: {s['ticks']} ticks, late ticks {s['late_ticks']}, "
        f"max lateness {late_ms:.2f} ms, stale stops {s['stale_stops']}, exit {res.exit_code}"
    )


if __name__ == "__main__":
    main()
