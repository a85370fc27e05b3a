"""The baseline comparison: fuzzy static / fuzzy dynamic / l-psi, under
observation drops and two camera-noise levels, on the paper's turning path.

Runs the grid through swarm sweep (resumable: rerunning reuses finished runs),
then prints a markdown table of the follower's RMS and max formation error
(mean over seeds, with the 95% confidence half-width) and, with --write,
replaces the table between the markers in that file. A run that
failed or missed a lockstep tick keeps the table from being written.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from formation_swarm.cliargs import USAGE_ERROR, Parser, integer, make_folder
from formation_swarm.proc import interrupt_on_stop_signals
from formation_swarm.sweep import MAX_JOBS, MAX_SEEDS, Job, Sweep, aggregate

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "fig7_turn_vn_dynamic.toml"
CONTROLLERS: dict[str, dict[str, Any]] = {
    "fuzzy, static V_N = 1.5": {"controller.vn": 1.5},
    "fuzzy, dynamic V_N": {"controller.vn": "dynamic"},
    "l-psi (Desai et al.)": {"controller.law": "lpsi"},
}
DROPS = (0.0, 0.1, 0.3)
# Camera noise, with the EKF told the same sigmas: the scenarios' default and Fig. 9's.
NOISE: dict[str, dict[str, Any]] = {
    "low": {},
    "high": {
        "camera.sigma_rho_m": 0.1, "camera.sigma_phi_deg": 5.0, "camera.sigma_beta_deg": 2.5,
        "controller.ekf.sigma_rho_m": 0.1, "controller.ekf.sigma_phi_rad": 0.0873,
        "controller.ekf.sigma_beta_rad": 0.0436,
    },
}  # fmt: skip
BEGIN, END = "<!-- results table: begin -->", "<!-- results table: end -->"


def jobs(seeds: Sequence[int]) -> list[Job]:
    out = []
    for ctrl, c_ov in CONTROLLERS.items():
        for noise, n_ov in NOISE.items():
            for drop in DROPS:
                label = f"{ctrl} | noise {noise} | obs drop {drop:.0%}"
                ov = {**c_ov, **n_ov, "links.obs_drop": drop}
                out += [Job(label, ov, s) for s in seeds]
    return out


def table(rows: Sequence[Mapping[str, Any]], seeds: int) -> str:
    agg = {(a["combination"], a["metric"]): a for a in aggregate(rows)}

    def cell(label: str, metric: str) -> str:
        a = agg.get((label, metric))
        if a is None:
            return "-"
        half = (a["ci95_high"] - a["ci95_low"]) / 2
        return f"{a['mean']:.2f} ± {half:.2f}"

    head = ["controller", "noise"] + [f"obs drop {d:.0%}" for d in DROPS]
    lines = [
        f"Follower RMS formation error, m: mean over {seeds} seeds ± 95% CI half-width "
        f"(max error in brackets, mean over seeds). Scenario `{SCENARIO.relative_to(ROOT)}`, lockstep.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for ctrl in CONTROLLERS:
        for noise in NOISE:
            cells = []
            for d in DROPS:
                label = f"{ctrl} | noise {noise} | obs drop {d:.0%}"
                mx = agg.get((label, "r2_max_m"))
                cells.append(cell(label, "r2_rms_m") + (f" [{mx['mean']:.2f}]" if mx else ""))
            lines.append(f"| {ctrl} | {noise} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def unfit_runs(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The runs that may not enter the table, each with the reason: a run that
    failed, and a lockstep run that missed a tick (the world stopped a robot for
    want of its answer: neither the controller's figure nor reproducible)."""
    out = []
    for r in rows:
        if r.get("exit_code") != 0:
            out.append(f"{r.get('run')}: exit code {r.get('exit_code')}")
        elif r.get("lockstep_misses") != 0:
            out.append(f"{r.get('run')}: {r.get('lockstep_misses')} lockstep misses")
    return out


def check_markers(path: Path) -> None:
    """Raise ValueError unless ``path`` is a file with the table's markers."""
    try:
        doc = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"--write {path}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
    if BEGIN not in doc or END not in doc:
        raise ValueError(f"--write {path}: has no {BEGIN} ... {END} markers")


def write_into(path: Path, text: str) -> None:
    check_markers(path)
    doc = path.read_text()
    new = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda _m: f"{BEGIN}\n{text}\n{END}", doc, flags=re.S)
    path.write_text(new)


def build_parser() -> Parser:
    ap = Parser(prog="swarm results", description=__doc__,
                epilog="example:\n  swarm results --seeds 10 --jobs 2 --write docs/results.md")  # fmt: skip
    ap.add_argument("--seeds", type=integer(2, MAX_SEEDS), default=10, metavar="N",
                    help=f"runs per cell of the table, seeds 0 to N-1, 2 to {MAX_SEEDS} (a confidence interval "
                    f"needs two); {len(jobs([0]))} runs per seed (default: 10)")  # fmt: skip
    ap.add_argument(
        "--jobs",
        type=integer(1, MAX_JOBS),
        default=None,
        metavar="J",
        help=f"runs at once, 1 to {MAX_JOBS} (default: the number of cores, {os.cpu_count() or 1})",
    )
    ap.add_argument("--out", default="sweeps/results", metavar="DIR",
                    help="the sweep folder, created if needed; finished runs there are reused "
                    "(default: sweeps/results)")  # fmt: skip
    ap.add_argument("--write", metavar="MARKDOWN", action="append", default=[],
                    help="replace the table between the markers in this file (repeatable)")  # fmt: skip
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        for target in args.write:
            check_markers(Path(target))  # before the runs, not after
        sweep = Sweep(SCENARIO, jobs(range(args.seeds)), args.out, workers=args.jobs)
        make_folder("--out", args.out)  # last: nothing made for a bad input
    except ValueError as exc:
        print(f"swarm results: {exc}", file=sys.stderr)
        return USAGE_ERROR
    interrupt_on_stop_signals()
    try:
        rows = sweep.run()
    except KeyboardInterrupt:
        return 130
    unfit = unfit_runs(rows)
    if unfit:
        # A failed run is run again by the next sweep; one with misses is kept, so it must be deleted.
        print(f"swarm results: {len(unfit)} runs cannot enter the table; delete their folders under "
              f"{Path(args.out) / 'runs'} and run again:\n  " + "\n  ".join(unfit[:10]), file=sys.stderr)  # fmt: skip
        return 1
    text = table(rows, args.seeds)
    print(text)
    for target in args.write:
        try:
            write_into(Path(target), text)
        except (OSError, ValueError) as exc:
            print(f"swarm results: {exc}", file=sys.stderr)
            return 1
    return 0
