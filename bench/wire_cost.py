"""What the wire recording (on unless ``swarm run --no-record-wire``, docs/replay.md) costs
the lockstep rate: the full fig11 run of bench/lockstep.py without and with
it, alternating in one invocation, the cost as the median of the rounds'
ratios (the rounds run under different loads).

    python bench/wire_cost.py [--repeat 7] [--ticks 3000] [--robots 3]
"""

from __future__ import annotations

import argparse
import os
import statistics

from lockstep import MIN_TICKS, integer, measure_full


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=integer(1), default=7, metavar="N", help="rounds (default 7)")
    ap.add_argument("--ticks", type=integer(MIN_TICKS), default=3000, metavar="N", help="ticks per run (default 3000)")
    ap.add_argument("--robots", type=integer(3, 500), default=3, metavar="N", help="robots (default 3)")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; {args.robots} robots")
    full: list[float] = []
    wired: list[float] = []
    for i in range(args.repeat):
        full.append(measure_full(args.ticks * 0.05, args.robots)[0])
        wired.append(measure_full(args.ticks * 0.05, args.robots, wire=True)[0])
        print(
            f"  round {i + 1}: full {full[-1]:7.0f} ticks/s, with the wire recording {wired[-1]:7.0f} ticks/s "
            f"({100 * (1 - wired[-1] / full[-1]):+.1f}%), load average {os.getloadavg()[0]:.2f}",
            flush=True,
        )
    cost = statistics.median(1 - w / f for w, f in zip(wired, full, strict=True))
    print(
        f"the wire recording: full {statistics.median(full):.0f} ticks/s without it, "
        f"{statistics.median(wired):.0f} with it: it costs {100 * cost:+.1f}% of the lockstep rate "
        f"(median of the rounds' ratios); load average after: {os.getloadavg()[0]:.2f}"
    )


if __name__ == "__main__":
    main()
