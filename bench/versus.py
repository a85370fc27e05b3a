"""Lockstep ticks/s of this checkout beside another install of the package,
alternating run by run in one invocation, so that their ratio holds on a
loaded machine (a refactor's before and after: the other install is, say, a
worktree of the commit before, with its own venv).

    python bench/versus.py --other /path/to/old/.venv/bin/swarm [--pairs 7]
                           [--scenario fig11_obstacles] [--robots N] [--set KEY=VALUE ...]

Each pair runs both in turn (which goes first alternates), `swarm run
SCENARIO --mode lockstep --no-logger`, and reads ticks/s (the world's loop)
and the trajectory digest from each summary. Prints the medians, their
ratio (this / other), the load average before and after, and whether the
digests agree (they must, for a refactor that changes no arithmetic).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

THIS = Path(sys.executable).with_name("swarm")
RUN_TIMEOUT_S = 600.0


def one_run(swarm: Path, args: argparse.Namespace, out: Path) -> tuple[float, str]:
    """Ticks/s and the trajectory digest of one lockstep run without the logger."""
    argv = [str(swarm), "run", args.scenario, "--mode", "lockstep", "--no-logger", "--out", str(out)]
    if args.robots:
        argv += ["--set", f"run.robots={args.robots}"]
    for kv in args.set:
        argv += ["--set", kv]
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=RUN_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired:
        sys.exit(f"versus: {swarm} did not finish within {RUN_TIMEOUT_S:g} s ({' '.join(argv)})")
    if done.returncode != 0:
        tail = "\n".join(done.stdout.splitlines()[-10:] + done.stderr.splitlines()[-10:])
        sys.exit(f"versus: {swarm} exited {done.returncode}:\n{tail}")
    summary = json.loads((out / "summary.json").read_text())
    return float(summary["ticks_per_s"]), str(summary["trajectory_digest"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--other", type=Path, required=True, help="the other install's swarm command")
    ap.add_argument("--pairs", type=int, default=7, help="pairs of runs (default 7)")
    ap.add_argument("--scenario", default="fig11_obstacles")
    ap.add_argument("--robots", type=int, default=None, help="run.robots (a scenario that takes it)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    if not args.other.is_file() or not os.access(args.other, os.X_OK):
        ap.error(f"--other {args.other}: not an executable file")
    if args.pairs < 1:
        ap.error("--pairs must be at least 1")
    load_before = os.getloadavg()
    rates: dict[str, list[float]] = {"this": [], "other": []}
    digests: dict[str, set[str]] = {"this": set(), "other": set()}
    work = Path(tempfile.mkdtemp(prefix="versus-"))
    try:
        for k in range(args.pairs):
            order = [("this", THIS), ("other", args.other)]
            for name, swarm in order if k % 2 == 0 else order[::-1]:
                rate, digest = one_run(swarm, args, work / f"{name}-{k}")
                rates[name].append(rate)
                digests[name].add(digest)
                shutil.rmtree(work / f"{name}-{k}", ignore_errors=True)
            print(
                f"pair {k + 1}/{args.pairs}: this {rates['this'][-1]:.0f}, other {rates['other'][-1]:.0f} ticks/s",
                flush=True,
            )
    except KeyboardInterrupt:
        print("versus: interrupted; the pairs so far:", file=sys.stderr)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if not rates["other"] or len(rates["this"]) != len(rates["other"]):
        rates = {name: r[: len(rates["other"])] for name, r in rates.items()}
    if not rates["this"]:
        return 130
    this, other = statistics.median(rates["this"]), statistics.median(rates["other"])
    load_after = os.getloadavg()
    print(f"scenario {args.scenario}, lockstep, no logger, {len(rates['this'])} pairs")
    print(f"  this:  median {this:.0f} ticks/s ({', '.join(f'{r:.0f}' for r in rates['this'])})")
    print(f"  other: median {other:.0f} ticks/s ({', '.join(f'{r:.0f}' for r in rates['other'])})")
    print(f"  ratio this/other: {this / other:.3f}")
    print(f"  load average before {load_before[0]:.1f}, after {load_after[0]:.1f}")
    same = digests["this"] == digests["other"] and len(digests["this"]) == 1
    seen = ", ".join(sorted(d[:12] for d in digests["this"] | digests["other"]))
    print(f"  trajectory digests: {'equal' if same else 'DIFFERENT'} ({seen})")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
