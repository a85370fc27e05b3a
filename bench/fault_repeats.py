"""Repeat lockstep runs with one fault each and print what repeated.

    python bench/fault_repeats.py [--runs 3] [--scenario fig11_obstacles] [FAULT ...]

For each fault (default: a kill, a restart, a freeze and a 15 s partition
of the whole formation from the world), N lockstep runs of the scenario with
the same seed: their trajectory digests, the ticks the world logged for the
fault, each return's recovery (ticks until the formation error is below
0.5 m, its size 5 s later) and the wall time the runs took. The digests of
one fault's runs must be equal; a line says so. For faults with an end, each
follower's mean error in each second after it, beside the same seconds of a
run without the fault (a fault that stopped the whole formation shifts its
timeline: compare with the 0.5 m line then, not with that run).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from formation_swarm.launch.launcher import Launch

DEFAULT_FAULTS = (
    "kill agent-3@20s",
    "restart agent-3@20s after=1",
    "freeze agent-2@15s for=3s",
    "partition 1,2,3@20s for=15s from=world",
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("faults", nargs="*", default=list(DEFAULT_FAULTS), help="faults, one per set of runs")
    ap.add_argument("--runs", type=int, default=3, help="runs per fault (default 3)")
    ap.add_argument("--scenario", default="fig11_obstacles")
    ap.add_argument("--seed", type=int, default=None)
    args = ap.parse_args(argv)
    failed = 0
    with tempfile.TemporaryDirectory(prefix="fault-repeats-") as tmp:
        for k, fault in enumerate(args.faults):
            digests, walls = [], []
            summary = {}
            for n in range(args.runs):
                t0 = time.monotonic()
                with Launch(
                    args.scenario,
                    seed=args.seed,
                    out=Path(tmp) / f"{k}-{n}",
                    logger=False,
                    faults=[fault],
                    progress=lambda _line: None,
                ) as launch:
                    res = launch.wait(timeout_s=600)
                walls.append(time.monotonic() - t0)
                summary = res.summary
                digests.append(summary.get("trajectory_digest"))
                print(
                    f"{fault}: run {n + 1}: exit {res.exit_code}, {summary.get('ticks')} ticks, "
                    f"digest {str(digests[-1])[:16]}, {walls[-1]:.1f} s",
                    flush=True,
                )
            same = len(set(digests)) == 1
            failed += not same
            (f,) = [x for x in summary.get("faults", []) if x.get("fault") == fault] or [{}]
            print(
                f"  {'the same digest' if same else 'DIFFERENT digests'} in {args.runs} runs; "
                f"median wall {statistics.median(walls):.1f} s"
            )
            events = ", ".join(f"{e['event']} R{e.get('robot')} at tick {e['tick']}" for e in f.get("events", []))
            print(f"  world: {events or '-'}; counted: {f.get('counts') or '-'}")
            for rec in f.get("recoveries", []):
                at, later = _m(rec.get("error_at_start_m")), _m(rec.get("error_after_window_m"))
                print(
                    f"  recovery of R{rec.get('robot')} from tick {rec.get('since_tick')}: error {at} at return, "
                    f"below 0.5 m after {rec.get('first_below_after_s')} s, {later} 5 s later"
                )
            windows = summary.get("error_windows") or {}
            if f.get("end_tick") is not None and windows:
                base = baseline(args, Path(tmp) / f"{k}-base")
                end_s = round(f["end_tick"] * summary.get("sim_time_s", 0) / max(1, summary.get("ticks", 1)))
                for rid, means in sorted((windows.get("mean_m") or {}).items()):
                    after = means[end_s : end_s + 10]
                    plain = base[rid][end_s : end_s + 10]
                    below = next((i for i, m in enumerate(after) if m < 0.5), None)
                    back = next((i for i, (m, b) in enumerate(zip(after, plain, strict=False)) if m <= b + 0.1), None)
                    print(
                        f"  R{rid}: mean error in each second after the fault's end: "
                        f"{', '.join(f'{m:.2f}' for m in after)} m (without the fault: "
                        f"{', '.join(f'{m:.2f}' for m in plain)} m); first second below 0.5 m: {below}, "
                        f"within 0.1 m of the run without the fault: {back}"
                    )
    return 1 if failed else 0


def _m(x: object) -> str:
    return f"{x:.2f} m" if isinstance(x, (int, float)) else "-"


def baseline(args: argparse.Namespace, folder: Path) -> dict[str, list[float]]:
    """Each follower's mean formation error per second in the run without faults."""
    with Launch(args.scenario, seed=args.seed, out=folder, logger=False, progress=lambda _line: None) as launch:
        res = launch.wait(timeout_s=600)
    return res.summary["error_windows"]["mean_m"]


if __name__ == "__main__":
    sys.exit(main())
