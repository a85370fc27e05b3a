"""``python -m formation_swarm.studies.margins``: the margins study's runs
(resumable), its rows and its three sections of docs/results.md."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from formation_swarm.studies import margins
from formation_swarm.studies.margins import avoidance, runs, text
from formation_swarm.studies.sections import check_markers, markers, write_all

SECTIONS = (
    ("claim a margins", text.claim_a_table),
    ("claim c margins", text.claim_c_table),
    ("nees", text.nees_table),
    ("avoidance on the paper's change", avoidance.paper_change_table),
    ("rank swap sensitivity", avoidance.rank_swap_table),
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m formation_swarm.studies.margins", description=__doc__)
    ap.add_argument("--seeds", type=int, default=30, help="seeds 0 to N-1 per row, 2 to 1000 (default: 30)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="runs at once (default: the cores)")
    ap.add_argument("--out", default="sweeps/margins", help="the folder of the runs' rows (reused when there)")
    ap.add_argument("--rows", default=None, metavar="CSV", help="write every run's row to this CSV")
    ap.add_argument("--write", action="append", default=[], metavar="MARKDOWN", help="the sections go there")
    args = ap.parse_args(argv)
    if not 2 <= args.seeds <= 1000 or not 1 <= args.jobs <= 64:
        print("margins: --seeds takes 2 to 1000, --jobs 1 to 64", file=sys.stderr)
        return 2
    writes = [Path(w) for w in args.write]
    try:
        for target in writes:
            for what, _make in SECTIONS:
                check_markers(target, *markers(what))
    except ValueError as exc:
        print(f"margins: {exc}", file=sys.stderr)
        return 2
    rows = runs.run_all(margins.plan(range(args.seeds)), Path(args.out), args.jobs)
    if args.rows:
        runs.write_csv(Path(args.rows), rows)
    for what, make in SECTIONS:
        section = make(rows)
        print(section + "\n")
        if not write_all(writes, section, *markers(what)):
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
