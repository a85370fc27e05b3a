"""Replay a set of lockstep runs and compare their trajectory digests with a
stored list: the check that a change to the world or the agents moved no
robot by a single bit.

Each case is a shipped scenario, a seed, overrides and faults; its line in the
list is ``CASE<TAB>DIGEST``. Record the list on the code before a change, then
check the changed code against it:

    python tools/digests.py --write /tmp/digests.txt [--seeds 0 1 2 3 4] [--only fig11]
    python tools/digests.py --check /tmp/digests.txt

``--check`` prints every case that differs and exits 1 if one does.
``--agents-per-process K`` runs every case with K robots' agents to a process
(``run.agents_per_process``): checked against a list written with K = 1, it
shows that sharing processes moves no robot.
``tools/digests.txt`` is the list recorded on the development machine
(Python 3.11, numpy 2.4, a CPU with AVX-512) since the cameras draw their
noise for the markers in view only (world.camera); another machine's libm,
or a CPU for which numpy picks other vector code (its arctan2), may give
other digests: record a list there first.
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

SCENARIOS = ("fig11_obstacles", "fig6_turn_vn_1_5", "fig6_turn_vn_2", "fig7_turn_vn_dynamic", "fig9_ekf_noise")
# Both control laws on two scenarios, and faults of every group on fig11.
LPSI = ("fig11_obstacles", "fig7_turn_vn_dynamic")
FAULTS = (
    "outliers 2@5s for=5s p=0.3",
    "drop obs:2,3@3s for=4s p=0.3",
    "wheel_noise 3@2s for=10s sigma_mps=0.05",
    "delay cmd:2@4s for=3s ticks=2",
    "range 3@10s for=5s m=3",
)

MANY = ((10, 56.0), (30, 10.0))


def cases(seeds: list[int]) -> list[tuple[str, str, int, dict[str, object], list[str]]]:
    """(name, scenario, seed, overrides, faults) of every case."""
    out: list[tuple[str, str, int, dict[str, object], list[str]]] = []
    for seed in seeds:
        for sc in SCENARIOS:
            out.append((f"{sc} seed={seed}", sc, seed, {}, []))
        for sc in LPSI:
            out.append((f"{sc} seed={seed} law=lpsi", sc, seed, {"controller.law": "lpsi"}, []))
        for fault in FAULTS:
            out.append((f"fig11_obstacles seed={seed} fault={fault}", "fig11_obstacles", seed, {}, [fault]))
        # Many robots: each camera sees several markers, some out of range.
        for n, duration in MANY:
            ov: dict[str, object] = {"run.robots": n, "leader.formation": "line", "run.duration_s": duration}
            out.append((f"fig11_obstacles seed={seed} robots={n} line {duration:g}s", "fig11_obstacles", seed, ov, []))
        ov = {"run.robots": 10, "leader.formation": "line", "run.duration_s": 20.0}
        fault = "outliers 4,7@5s for=5s p=0.3"
        name = f"fig11_obstacles seed={seed} robots=10 line 20s fault={fault}"
        out.append((name, "fig11_obstacles", seed, ov, [fault]))
    return out


def digest(scenario: str, seed: int, overrides: dict[str, object], faults: list[str], tmp: Path) -> str:
    with Launch(
        scenario,
        seed=seed,
        overrides=overrides,
        faults=faults,
        logger=False,
        out=tmp / f"r{time.time_ns()}",
        progress=lambda _line: None,
    ) as launch:
        res = launch.wait(timeout_s=900.0)
    if res.exit_code != 0 or not res.summary.get("trajectory_digest"):
        return f"failed (exit {res.exit_code}, {res.run_dir})"
    return str(res.summary["trajectory_digest"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument("--write", metavar="FILE", help="record the digests into FILE")
    what.add_argument("--check", metavar="FILE", help="compare the digests with FILE's")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--only", default="", help="only the cases whose name contains this")
    ap.add_argument("--agents-per-process", type=int, default=1, metavar="K", help="run.agents_per_process (default 1)")
    args = ap.parse_args()
    todo = [c for c in cases(args.seeds) if args.only in c[0]]
    stored: dict[str, str] = {}
    if args.check:
        for line in Path(args.check).read_text().splitlines():
            name, _, dig = line.partition("\t")
            stored[name] = dig
        todo = [c for c in todo if c[0] in stored]
    k = args.agents_per_process
    print(f"{len(todo)} runs, {k} agents to a process; load average {os.getloadavg()[0]:.2f}", flush=True)
    same = differ = 0
    with tempfile.TemporaryDirectory() as tmp:
        for name, sc, seed, overrides, faults in todo:
            got = digest(sc, seed, {**overrides, "run.agents_per_process": args.agents_per_process}, faults, Path(tmp))
            if args.write:
                with open(args.write, "a") as f:
                    f.write(f"{name}\t{got}\n")
                print(f"{got[:16]}  {name}", flush=True)
            elif got == stored[name] and not got.startswith("failed"):
                same += 1
            else:
                differ += 1
                print(f"DIFFERS {name}: {stored[name][:16]} -> {got[:16]}", flush=True)
    if args.check:
        print(f"{same} of {same + differ} digests equal")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
