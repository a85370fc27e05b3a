"""Many lockstep runs of one scenario: seeds x parameter values, in parallel.

Every combination of the --set values is run with each seed, as many runs at
once as --jobs (default: the number of cores). Each run keeps its own folder
under DIR/runs/; a run whose summary is already there is not run again, so an
interrupted sweep resumes where it stopped. DIR/runs.csv holds one row of
metrics per run and DIR/aggregate.csv, per combination, the mean, standard
deviation and 95% confidence interval (Student t) of every metric, and
DIR/aggregate.png the main ones (formation error RMS and maximum, EKF target
error, least distance between robots) with their intervals against the swept
value, one line per follower. The sweep ends with a table of the main
metrics per combination on the console.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import threading
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.common.checks import SEED_MAX
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser, integer, make_folder, seed
from formation_swarm.runtime.proc import interrupt_on_stop_signals
from formation_swarm.studies.jobs import Job, grid, parse_set, slug
from formation_swarm.studies.tables import aggregate, brief, metrics, summary_table, write_csv

# The launcher and the scenario loader bring Zenoh, scipy and filterpy (1-2 s
# of imports): they are imported where a sweep needs them, so that --help and
# a bad flag answer at once.
if TYPE_CHECKING:
    from formation_swarm.launch.launcher import Launch, RunResult


class Sweep:
    def __init__(
        self,
        scenario: str | Path,
        jobs: Sequence[Job],
        out: str | Path,
        *,
        workers: int | None = None,
        logger: bool = False,
        progress: Callable[[str], None] = print,
        run_timeout_s: float = 600.0,
        faults: Sequence[Any] = (),
    ) -> None:
        self.scenario = Path(scenario)
        from formation_swarm.spec import files as scenario_files
        from formation_swarm.spec import scenario as scenario_mod

        self.faults = list(faults)  # added to every run (formation_swarm.common.faults)
        scenario_mod.load(self.scenario, None, self.faults)  # a bad scenario or fault fails here, not in every run
        contexts = {}
        said: list[str] = []
        for label, ov in {j.label: j.overrides for j in jobs}.items():
            with warnings.catch_warnings():  # the loader's warnings: said once below, not as Python warnings
                warnings.simplefilter("ignore", scenario_mod.ScenarioWarning)
                sc = scenario_mod.load(self.scenario, dict(ov), self.faults)  # and so does a bad --set value
            said += [f"[sweep] {self.scenario.stem} {label or 'as shipped'}: {w}" for w in sc.warnings]
            contexts[label] = scenario_files.dumps(sc.with_seed(0).raw)
        self.jobs = [replace(j, context=contexts[j.label]) for j in jobs]
        self.out = Path(out)
        self.workers = max(1, workers or os.cpu_count() or 1)
        self.logger = logger
        self.progress = progress
        for line in said:
            progress(line)
        self.run_timeout_s = run_timeout_s
        self._stop = threading.Event()
        self._live: set[Launch] = set()
        self._lock = threading.Lock()

    def run(self) -> list[dict[str, Any]]:
        """Runs what is missing, then writes runs.csv and aggregate.csv; the rows."""
        runs_dir = self.out / "runs"
        runs_dir.mkdir(parents=True, exist_ok=True)
        rows: dict[str, dict[str, Any]] = {}
        todo = []
        for job in self.jobs:
            done = _load_done(runs_dir / job.name)
            if done is not None:
                rows[job.name] = self._row(job, done)
            else:
                todo.append(job)
        total = len(self.jobs)
        if rows:
            self.progress(f"[sweep] {len(rows)}/{total} runs already done in {runs_dir}; {len(todo)} to go")
        if todo:  # the spawner's server, from this thread: it starts it with Ctrl-C ignored (a pool's cannot)
            from formation_swarm.runtime import spawner

            spawner.warm()
        try:
            with ThreadPoolExecutor(max_workers=self.workers) as pool:
                try:
                    self._loop(pool, todo, rows, total)
                except KeyboardInterrupt:
                    # Inside the pool's block: leaving it waits for every run in flight,
                    # which must be told to stop first.
                    self.progress("[sweep] interrupted: stopping the runs in flight (finished runs are kept)")
                    self._stop.set()
                    with self._lock:
                        for launch in list(self._live):
                            launch.interrupt()
                    raise
        finally:
            self._write(rows)
            ordered = [rows[j.name] for j in self.jobs if j.name in rows]
            if ordered:  # interrupted too: the figure of what finished, as the tables
                from formation_swarm.studies.sweep import figure as sweep_figure

                sweep_figure.write(self.out / "aggregate.png", aggregate(ordered), self.jobs, self.scenario.stem)
        return ordered

    def _loop(self, pool: ThreadPoolExecutor, todo: list[Job], rows: dict[str, dict[str, Any]], total: int) -> None:
        """Keeps ``workers`` runs of ``todo`` going until all are done; each one's
        row goes into ``rows`` and the tables as it ends."""
        runs_dir = self.out / "runs"
        started = time.monotonic()
        finished = 0
        pending: dict[Future[RunResult | None], Job] = {}
        queue = list(reversed(todo))
        while queue or pending:
            while queue and len(pending) < self.workers and not self._stop.is_set():
                job = queue.pop()
                pending[pool.submit(self._one, job, runs_dir / job.name)] = job
            if not pending:
                break
            done_set, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done_set:
                job = pending.pop(fut)
                res = fut.result()
                if res is None:
                    continue
                finished += 1
                rows[job.name] = self._row(job, res.summary)
                self._write(rows)
                el = time.monotonic() - started
                eta = el / finished * (len(todo) - finished)
                self.progress(
                    f"[sweep] {len(rows)}/{total} {job.name}: exit {res.exit_code}, "
                    f"{brief(rows[job.name])} ({el:.0f} s, about {eta:.0f} s left)"
                )

    def _one(self, job: Job, run_dir: Path) -> RunResult | None:
        from formation_swarm.launch.launcher import Launch

        for attempt in (1, 2):
            if self._stop.is_set():
                return None
            with Launch(
                self.scenario,
                seed=job.seed,
                out=run_dir,
                overrides=dict(job.overrides),
                logger=self.logger,
                faults=self.faults,
                progress=lambda _line: None,
            ) as launch:
                with self._lock:
                    self._live.add(launch)
                    if self._stop.is_set():  # a Ctrl-C came while it started
                        launch.interrupt()
                try:
                    res = launch.wait(timeout_s=self.run_timeout_s)
                finally:
                    with self._lock:
                        self._live.discard(launch)
            gap = summary_mod.recording_gap(res.summary)
            if gap is None or attempt == 2:
                return res
            kept = run_dir.with_name(run_dir.name + ".incomplete")
            shutil.rmtree(kept, ignore_errors=True)
            run_dir.rename(kept)  # its logs and recording, to look into the loss
            self.progress(
                f"[sweep] {job.name}: {gap}; running it again (its metrics would miss those ticks; "
                f"this attempt is kept in {kept})"
            )
        return res

    def _row(self, job: Job, summary: Mapping[str, Any]) -> dict[str, Any]:
        return {"combination": job.label, "seed": job.seed, "run": job.name, **metrics(summary)}

    def _write(self, rows: Mapping[str, dict[str, Any]]) -> None:
        ordered = [rows[j.name] for j in self.jobs if j.name in rows]
        if not ordered:  # nothing finished (an early Ctrl-C): no empty tables
            return
        write_csv(self.out / "runs.csv", ordered)
        write_csv(self.out / "aggregate.csv", aggregate(ordered))


def _load_done(run_dir: Path) -> dict[str, Any] | None:
    """The summary of a run that completed (exit 0) with its whole recording,
    else None (to be run again)."""
    try:
        s = json.loads((run_dir / "summary.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return s if isinstance(s, dict) and s.get("exit_code") == 0 and summary_mod.recording_gap(s) is None else None


@dataclass(frozen=True)
class Unfit:
    """A run that may not enter the table: its name, its exit code (not 0: it
    failed) and its lockstep misses (not 0: it missed a tick)."""

    run: Any
    exit_code: Any
    lockstep_misses: Any


def unfit_of(rows: Sequence[Mapping[str, Any]]) -> list[Unfit]:
    """The runs that may not enter the table: a run that failed, and a lockstep
    run that missed a tick (the world stopped a robot for want of its answer:
    neither the controller's figure nor reproducible)."""
    return [
        Unfit(r.get("run"), r.get("exit_code"), r.get("lockstep_misses"))
        for r in rows
        if r.get("exit_code") != 0 or r.get("lockstep_misses") != 0
    ]


def unfit_runs(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The runs that may not enter the table (``unfit_of``), each with the reason."""
    return [
        f"{u.run}: exit code {u.exit_code}" if u.exit_code != 0 else f"{u.run}: {u.lockstep_misses} lockstep misses"
        for u in unfit_of(rows)
    ]


def run_sweeps(sweeps: Mapping[str, Sweep], out: Path) -> dict[str, list[dict[str, Any]]] | None:
    """Every sweep's rows, for one table (swarm results); None, having said why,
    when a run cannot enter it."""
    rows = {name: sweep.run() for name, sweep in sweeps.items()}
    unfit = [why for r in rows.values() for why in unfit_runs(r)]
    if unfit:
        # A failed run is run again by the next sweep; one with misses is kept, so it must be deleted.
        print(
            f"swarm results: {len(unfit)} runs cannot enter the table; delete their folders under "
            f"{out} and run again:\n  " + "\n  ".join(unfit[:10]),
            file=sys.stderr,
        )
        return None
    return rows


MAX_SEEDS = 10_000  # runs per combination: each takes seconds to minutes
MAX_JOBS = 256  # runs at once, each of several processes
EPILOG = """\
examples:
  swarm sweep fig7_turn_vn_dynamic --seeds 20 --set controller.vn=1.5,2,dynamic
  swarm sweep fig11_obstacles --seeds 10 --set links.obs_drop=0,0.1,0.3 --jobs 2 --out sweeps/drops
"""


def build_parser() -> Parser:
    ap = Parser(prog="swarm sweep", description=__doc__, epilog=EPILOG)
    ap.add_argument("scenario", help="a shipped scenario's name (see: swarm scenarios) or a scenario file (TOML)")
    ap.add_argument(
        "--seeds",
        type=integer(1, MAX_SEEDS),
        required=True,
        metavar="N",
        help=f"runs per combination, one per seed, 1 to {MAX_SEEDS} (required)",
    )
    ap.add_argument(
        "--seed-start",
        type=seed,
        default=0,
        metavar="S",
        help="the first seed: the runs use seeds S to S+N-1 (default: 0)",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=V1,V2",
        help="a scenario key and the values to sweep, e.g. controller.vn=1.5,dynamic (repeatable: "
        "the grid is every combination)",
    )
    ap.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="'KIND TARGET@TIME ...'",
        help="a fault in every run, e.g. 'wheel_noise *@0s sigma_mps=0.1' (repeatable; docs/faults.md)",
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
        help="the sweep folder, created if needed (default: sweeps/<scenario name>)",
    )
    ap.add_argument(
        "--logger",
        action="store_true",
        help="record each run (recording.rrd): needed for the EKF target errors, slower",
    )
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.seed_start + args.seeds - 1 > SEED_MAX:
        print(
            f"swarm sweep: argument --seed-start: seeds S to S+N-1 must stay within 2**63 - 1, got S "
            f"{args.seed_start} and N {args.seeds}",
            file=sys.stderr,
        )
        return USAGE_ERROR
    try:
        sets = [parse_set(s) for s in args.set]
        if len({k for k, _ in sets}) < len(sets):
            twice = next(k for i, (k, _) in enumerate(sets) if k in [j for j, _ in sets[:i]])
            raise ValueError(f"--set {twice} is given twice: put its values in one, e.g. {twice}=1.5,2")
        from formation_swarm.spec import scenario as scenario_mod

        sc = scenario_mod.load(args.scenario)
        jobs = [
            Job(label, ov, run_seed)
            for label, ov in grid(sets)
            for run_seed in range(args.seed_start, args.seed_start + args.seeds)
        ]
        out = Path(args.out) if args.out else Path("sweeps") / slug(sc.name)
        sweep = Sweep(args.scenario, jobs, out, workers=args.jobs, logger=args.logger, faults=args.fault)
        make_folder("--out" if args.out else "sweep folder", out)  # last: nothing made for a bad input
    except (ValueError, OSError) as exc:
        print(f"swarm sweep: {exc}", file=sys.stderr)
        return USAGE_ERROR
    interrupt_on_stop_signals()  # both stop the runs in flight cleanly
    try:
        rows = sweep.run()
    except KeyboardInterrupt:
        return 130
    failed = [r["run"] for r in rows if r.get("exit_code") != 0]
    if rows:
        print(f"[sweep] mean ± 95% confidence half-width over the seeds of each combination:\n{summary_table(rows)}")
    print(
        f"[sweep] {len(rows)} runs; tables: {out / 'runs.csv'}, {out / 'aggregate.csv'}; "
        f"figure: {out / 'aggregate.png'}"
    )
    if failed:
        print(f"[sweep] {len(failed)} runs failed: {', '.join(failed[:10])}", file=sys.stderr)
        return 1
    return 0
