"""Where a run's CPU goes, thread by thread: N robots in a line on fig11's
path in real time, the logger on; over a window of the run, each process's
CPU per tick (user + system, from ``/proc/<pid>/task/*/stat``) split by
thread: the Python threads (named after the process) and Zenoh's runtime
threads (``rx-0``, ``net-0``, ...), and Rerun's in the logger. The followers
are averaged; the leader (agent-1) is shown apart. With ``--agents-per-process K``
the shared processes' CPU is given per robot.

    python bench/threads.py [--robots 100] [--window 10] [--agents-per-process K]

Ticks are counted on the run's sim clock over the window, so a run that
falls behind the wall clock shows its CPU per tick it made, not per 50 ms.
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formation_swarm.launch.launcher import Launch  # noqa: E402

SCENARIO = ROOT / "scenarios" / "fig11_obstacles.toml"
TICKS_PER_S = os.sysconf("SC_CLK_TCK")


def threads(pid: int) -> dict[str, tuple[str, float, float]]:
    """Per thread id: its name, user and system CPU seconds so far."""
    out: dict[str, tuple[str, float, float]] = {}
    try:
        tasks = list(Path(f"/proc/{pid}/task").iterdir())
    except OSError:
        return out  # the process ended
    for task in tasks:
        try:
            name = (task / "comm").read_text().strip()
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # the thread ended
        out[task.name] = (name, int(fields[11]) / TICKS_PER_S, int(fields[12]) / TICKS_PER_S)
    return out


def kind(name: str, process: str) -> str:
    """A thread's group: Python (named like its process), or its name without the worker number."""
    if name == process[:15] or name.startswith("/") or name.startswith("python"):
        return "python"
    return name.rstrip("0123456789").rstrip("-") or name


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, default=100)
    ap.add_argument("--window", type=float, default=10.0, help="wall seconds measured, after 2 s of sim (default 10)")
    ap.add_argument("--agents-per-process", type=int, default=1, metavar="K", help="robots per agent process")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}", flush=True)
    overrides = {
        "run.robots": args.robots,
        "leader.formation": "line",
        "run.duration_s": args.window + 8.0,
        "run.agents_per_process": args.agents_per_process,
    }
    with (
        tempfile.TemporaryDirectory() as tmp,
        Launch(
            SCENARIO, mode="realtime", out=Path(tmp) / "run", overrides=overrides, logger=True, progress=lambda _l: None
        ) as launch,
    ):
        if not launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=600.0):
            raise SystemExit(f"{args.robots} robots: the run did not reach 2 s of sim")
        pids = launch.pids()
        before = {name: threads(pid) for name, pid in pids.items()}
        sim0 = launch.sim_time()
        time.sleep(args.window)  # a measuring window, not a wait for a condition
        after = {name: threads(pid) for name, pid in pids.items()}
        ticks = (launch.sim_time() - sim0) / launch.sc.dt_s
        launch.wait(timeout_s=600.0)
    gone = sorted(name for name in pids if not after[name])
    if gone:
        print(f"ended within the window (not counted): {', '.join(gone)}")
    print(f"{args.robots} robots, {ticks:.0f} ticks in {args.window:g} s; load average {os.getloadavg()[0]:.2f}")
    groups: dict[str, collections.Counter[str]] = {}
    count: collections.Counter[str] = collections.Counter()
    for name in pids:
        group = "follower" if name.startswith("agent-") and name != "agent-1" else name
        if name.startswith("agents-"):  # K robots in one process: per robot
            first, _, last = name[len("agents-") :].partition("-")
            group, robots = "robot of a shared process", int(last or first) - int(first) + 1
        else:
            robots = 1
        count[group] += robots
        per = groups.setdefault(group, collections.Counter())
        for tid, (tname, user, system) in after[name].items():
            _, user0, system0 = before[name].get(tid, (tname, 0.0, 0.0))
            per[kind(tname, name)] += user + system - user0 - system0
    for group, per in groups.items():
        n, total = count[group], sum(per.values())
        parts = ", ".join(f"{k} {1e3 * v / n / ticks:.3f}" for k, v in per.most_common() if v > 0)
        label = f"{group} (mean of {n})" if n > 1 else group
        print(f"{label}: {1e3 * total / n / ticks:.3f} ms per tick: {parts}")


if __name__ == "__main__":
    main()
