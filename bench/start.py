"""Start-up cost of a run's processes: each role forked from the spawner (the
default) against each started with exec (``python -m ...``), side by side.

For N robots in a line (lockstep, no logger, 1 s of sim time), alternating the
two ways REPEATS times: the wall time from the launch to the first tick (every
process imported, connected and ready), the whole run's wall time, and the
memory the agents hold at the first tick (PSS, which counts shared pages once,
and RSS), as medians.

    python bench/start.py [--robots 10 30] [--repeats 3]
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

from formation_swarm.launch.launcher import Launch  # noqa: E402


def _memory_kb(pid: int) -> tuple[int, int]:
    """(PSS, RSS) of a process, kB (0, 0 when it is gone)."""
    pss = rss = 0
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                pss = int(line.split()[1])
            elif line.startswith("Rss:"):
                rss = int(line.split()[1])
    except OSError:
        pass
    return pss, rss


def one(robots: int, fork: bool, tmp: Path) -> dict[str, float]:
    overrides = {"run.robots": robots, "run.duration_s": 1.0, "leader.formation": "line"}
    t0 = time.monotonic()
    with Launch(
        ROOT / "scenarios" / "fig11_obstacles.toml",
        out=tmp / f"{'fork' if fork else 'exec'}-{robots}-{t0}",
        overrides=overrides,
        logger=False,
        fork=fork,
        progress=lambda _l: None,
    ) as launch:
        launch.start()
        if not launch.wait_until(lambda: launch.sim_time() >= 0.0, timeout_s=600.0):
            raise SystemExit("the run did not reach its first tick within 600 s")
        ready_s = time.monotonic() - t0
        mem = [_memory_kb(pid) for name, pid in launch.pids().items() if name.startswith("agent-")]
        res = launch.wait(timeout_s=600.0)
    if res.exit_code != 0:
        raise SystemExit(f"run failed ({res.exit_code}): {res.run_dir}")
    return {
        "ready_s": ready_s,
        "run_s": time.monotonic() - t0,
        "pss_mb": statistics.mean(p for p, _ in mem) / 1024,
        "rss_mb": statistics.mean(r for _, r in mem) / 1024,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, nargs="+", default=[10, 30])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.robots:
            got: dict[bool, list[dict[str, float]]] = {True: [], False: []}
            for i in range(args.repeats):
                for fork in (True, False) if i % 2 == 0 else (False, True):
                    got[fork].append(one(n, fork, Path(tmp)))
            med = {f: {k: statistics.median(r[k] for r in rows) for k in rows[0]} for f, rows in got.items()}
            for fork in (False, True):
                m = med[fork]
                how = "forked" if fork else "exec  "
                print(
                    f"{n:4d} robots, {how}: first tick after {m['ready_s']:6.2f} s, run {m['run_s']:6.2f} s, "
                    f"per agent PSS {m['pss_mb']:5.1f} MB, RSS {m['rss_mb']:5.1f} MB"
                )
            print(
                f"{n:4d} robots: forked/exec start-up time {med[True]['ready_s'] / med[False]['ready_s']:.2f}, "
                f"PSS {med[True]['pss_mb'] / med[False]['pss_mb']:.2f}"
            )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
