"""The baseline comparison: fuzzy static / fuzzy dynamic / l-psi, under
observation drops and two camera-noise levels, on the paper's turning path;
or, with --claims, the paper's claims a-d measured seed by seed (and, as
shipped, claim d's runs without the avoidance beside them); or, with
--sensitivity, those claims at every value of one setting at a time.

Runs the grid through swarm sweep, lockstep, one process per robot; the
claims and the sensitivity step their runs in one process instead
(studies.engine_sweep: the lockstep runs' very rows). Resumable: rerunning
reuses finished runs. It then prints a markdown table of the follower's
RMS and max formation error (mean over seeds, with the 95% confidence
half-width) and, with --write, replaces the table between the markers in
that file. --set changes a scenario key in every run (e.g.
robot.wheel_noise_mps=0.1); the table then goes between markers that name
the setting, so tables of several settings live side by side. A run that
failed or missed a lockstep tick keeps the table from being written.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser, integer, make_folder
from formation_swarm.runtime.proc import interrupt_on_stop_signals
from formation_swarm.spec.files import parse_overrides
from formation_swarm.studies import claims, sensitivity
from formation_swarm.studies.jobs import Job, settings_text
from formation_swarm.studies.sections import BEGIN, END, check_markers, markers, write_all
from formation_swarm.studies.sensitivity import run as sensitivity_run
from formation_swarm.studies.sweep import MAX_JOBS, MAX_SEEDS, Sweep, run_sweeps
from formation_swarm.studies.tables import aggregate

ROOT = Path(__file__).resolve().parents[2]
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
        "camera.sigma_rho_m": 0.1,
        "camera.sigma_phi_deg": 5.0,
        "camera.sigma_beta_deg": 2.5,
        "controller.ekf.sigma_rho_m": 0.1,
        "controller.ekf.sigma_phi_rad": 0.0873,
        "controller.ekf.sigma_beta_rad": 0.0436,
    },
}


def _label(ctrl: str, noise: str, drop: float, settings: Mapping[str, Any]) -> str:
    label = f"{ctrl} | noise {noise} | obs drop {drop:.0%}"
    return f"{label} | {settings_text(settings)}" if settings else label


def jobs(seeds: Sequence[int], settings: Mapping[str, Any] | None = None) -> list[Job]:
    settings = dict(settings or {})
    varied = {"links.obs_drop"} | {k for ov in (*CONTROLLERS.values(), *NOISE.values()) for k in ov}
    if clash := sorted(varied & set(settings)):
        raise ValueError(f"--set {clash[0]}: the table varies that key itself")
    out = []
    for ctrl, c_ov in CONTROLLERS.items():
        for noise, n_ov in NOISE.items():
            for drop in DROPS:
                ov = {**c_ov, **n_ov, "links.obs_drop": drop, **settings}
                out += [Job(_label(ctrl, noise, drop, settings), ov, s) for s in seeds]
    return out


def table(rows: Sequence[Mapping[str, Any]], seeds: int, settings: Mapping[str, Any] | None = None) -> str:
    settings = dict(settings or {})
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
        f"(max error in brackets, mean over seeds). Scenario `{SCENARIO.relative_to(ROOT)}`, lockstep"
        + (f", with {settings_text(settings)}." if settings else "."),
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for ctrl in CONTROLLERS:
        for noise in NOISE:
            cells = []
            for d in DROPS:
                label = _label(ctrl, noise, d, settings)
                mx = agg.get((label, "r2_max_m"))
                cells.append(cell(label, "r2_rms_m") + (f" [{mx['mean']:.2f}]" if mx else ""))
            lines.append(f"| {ctrl} | {noise} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def build_parser() -> Parser:
    ap = Parser(
        prog="swarm results",
        description=__doc__,
        epilog="examples:\n  swarm results --seeds 10 --jobs 2 --write docs/results.md\n"
        "  swarm results --claims --seeds 10 --jobs 1 --set robot.wheel_noise_mps=0.1 "
        "--write docs/results.md",
    )
    _add_run_arguments(ap)
    _add_study_arguments(ap)
    return ap


def _add_run_arguments(ap: Parser) -> None:
    """How many runs, where, and where the table goes."""
    ap.add_argument(
        "--seeds",
        type=integer(2, MAX_SEEDS),
        default=10,
        metavar="N",
        help=f"runs per cell of the table, seeds 0 to N-1, 2 to {MAX_SEEDS} (a confidence interval "
        f"needs two); {len(jobs([0]))} runs per seed (default: 10)",
    )
    ap.add_argument(
        "--jobs",
        type=integer(1, MAX_JOBS),
        default=None,
        metavar="J",
        help=f"runs at once, 1 to {MAX_JOBS} (default: the number of cores, {os.cpu_count() or 1})",
    )
    ap.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="the sweep folder, created if needed; finished runs there are reused "
        "(default: sweeps/results, or sweeps/claims with --claims)",
    )
    ap.add_argument(
        "--write",
        metavar="MARKDOWN",
        action="append",
        default=[],
        help="replace the table between the markers in this file (repeatable): "
        f"{BEGIN} ... {END}, or with --claims and --set, e.g. "
        f"{markers('claims', 'robot.wheel_noise_mps=0.1')[0]} ...",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scenario key for every run, e.g. robot.wheel_noise_mps=0.1 (repeatable; not a key the table varies)",
    )


def _add_study_arguments(ap: Parser) -> None:
    """The claims and the sensitivity studies instead of the baseline table."""
    ap.add_argument(
        "--claims",
        action="store_true",
        help=f"measure the paper's claims a-d instead ({len(claims.SWEEPS)} runs per seed, of the "
        "scenarios of tests/system/test_claims.py)",
    )
    ap.add_argument(
        "--rows",
        metavar="CSV",
        default=None,
        help="with --claims: also write every run's row (sweep, seed and its metrics) to this CSV, "
        "the data tests/system/test_claims.py checks the claims over; with --sensitivity: put the "
        "rows of the axes run into this CSV (axis, value, sweep, seed, metrics; the other axes' rows are "
        "kept) and write the summary of every claim along every axis in it between "
        f"{sensitivity_run.WHERE[0]} ... markers",
    )
    ap.add_argument(
        "--sensitivity",
        action="store_true",
        help="measure the claims at every value of one setting at a time (the leader's speed, the "
        "observations' drops, the camera's noise, the wheels' noise and bias), with l-psi and static "
        "V_N 1.7 and 1.8 beside; "
        "writes a figure per setting into --figures and, with --write, its section between "
        f"{markers('sensitivity', 'leader_speed')[0]} ... markers",
    )
    ap.add_argument(
        "--axis",
        action="append",
        default=[],
        choices=list(sensitivity.AXIS_NAMES),
        help="with --sensitivity: only this setting (repeatable; default: all)",
    )
    ap.add_argument(
        "--figures",
        default="docs/figures",
        metavar="DIR",
        help="with --sensitivity: where the figures go, sensitivity-<setting>.png (default: docs/figures)",
    )


def claim_sweeps(seeds: Sequence[int], settings: Mapping[str, Any], out: Path, workers: int | None) -> dict[str, Sweep]:
    """One sweep per scenario the claims are measured on, each in its own folder under ``out``."""
    return sensitivity.plan(seeds, settings, [], out, workers=workers)


@dataclass
class _Plan:
    """What a command line asks for, checked before any run."""

    settings: dict[str, Any]
    axes: list[sensitivity.Axis] = field(default_factory=list)  # --sensitivity: the settings to vary
    sweeps: dict[str, Sweep] = field(default_factory=dict)  # otherwise: the sweeps of the table
    # The tables made of the sweeps' rows, each with its markers in the --write files.
    tables: list[tuple[tuple[str, str], Callable[[claims.Rows], str]]] = field(default_factory=list)


def _tables(args: argparse.Namespace, settings: dict[str, Any]) -> list[tuple[tuple[str, str], Callable[..., str]]]:
    """The tables of the command line, each with its markers: the baseline's, or the claims' and,
    as shipped (no --set), claim d's ablation of the avoidance."""
    said = settings_text(settings)
    if not args.claims:
        return [(markers("results table", said), lambda rows: table(rows[""], args.seeds, settings))]
    out = [(markers("claims", said), lambda rows: claims.table(rows, said))]
    if not settings:
        out.append((markers("avoidance ablation"), claims.avoidance_table))
    return out


def _plan(args: argparse.Namespace, out: Path, writes: Sequence[Path]) -> _Plan:
    """The runs and the markers of the command line; ValueError for a bad input, before
    anything is made."""
    if args.sensitivity and (args.claims or args.set):
        raise ValueError("--sensitivity varies its own settings: it takes neither --claims nor --set")
    if args.axis and not args.sensitivity:
        raise ValueError("--axis needs --sensitivity")
    if args.rows and not (args.claims or args.sensitivity):
        raise ValueError("--rows needs --claims or --sensitivity")
    plan = _Plan(parse_overrides(args.set))
    if args.sensitivity:
        plan.axes = [sensitivity.AXIS_NAMES[a] for a in args.axis] or list(sensitivity.AXES)
        wanted = [markers("sensitivity", axis.name) for axis in plan.axes]
        wanted += [sensitivity_run.WHERE, sensitivity_run.SWAP] if args.rows else []
    else:
        plan.tables = _tables(args, plan.settings)
        wanted = [marks for marks, _make in plan.tables]
        if args.claims:
            plan.sweeps = claim_sweeps(range(args.seeds), plan.settings, out, args.jobs)
        else:
            plan.sweeps = {"": Sweep(SCENARIO, jobs(range(args.seeds), plan.settings), out, workers=args.jobs)}
    for target in writes:  # before the runs, not after
        for marks in wanted:
            check_markers(target, *marks)
    if args.sensitivity and Path(args.figures).exists() and not Path(args.figures).is_dir():
        raise ValueError(f"--figures {args.figures}: is an existing file, not a folder")
    make_folder("--out", out)  # last: nothing made for a bad input
    if args.sensitivity:
        make_folder("--figures", Path(args.figures))
    return plan


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    out = Path(args.out or ("sweeps/claims" if args.claims or args.sensitivity else "sweeps/results"))
    writes = [Path(t) for t in args.write]
    try:
        plan = _plan(args, out, writes)
    except ValueError as exc:
        print(f"swarm results: {exc}", file=sys.stderr)
        return USAGE_ERROR
    interrupt_on_stop_signals()
    try:
        if args.sensitivity:
            return sensitivity_run.run(
                plan.axes,
                args.seeds,
                out,
                workers=args.jobs,
                figures=Path(args.figures),
                writes=writes,
                rows_csv=Path(args.rows) if args.rows else None,
            )
        if args.claims:  # stepped in one process: the lockstep runs' rows (studies.engine_sweep)
            from formation_swarm.studies.engine_sweep import EngineSweep, run_engine_sweeps

            rows = run_engine_sweeps(cast("dict[str, EngineSweep]", plan.sweeps), out)
        else:
            rows = run_sweeps(plan.sweeps, out)
    except KeyboardInterrupt:
        return 130
    if rows is None:
        return 1
    if args.rows:
        try:
            claims.write_rows(Path(args.rows), rows)
        except OSError as exc:
            print(f"swarm results: --rows {args.rows}: cannot write it ({exc.strerror or exc})", file=sys.stderr)
            return 1
    for marks, make in plan.tables:
        text = make(rows)
        print(text)
        if not write_all(writes, text, *marks):
            return 1
    return 0
