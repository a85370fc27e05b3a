"""A sweep's runs stepped in this process (studies.engine_run) instead of
one process per robot: the lockstep runs' trajectories bit for bit, and
their rows (tables.metrics) to the last digit, in a fraction of the time.
``swarm results --claims`` and ``--sensitivity`` run their sweeps so.

An ``EngineSweep`` is a ``Sweep`` (the same jobs, folder, faults and
whether the logger records); ``run_all`` runs every missing run of
several sweeps in one pool, keeps each row as JSON in its sweep's
``runs/`` folder, named as the lockstep run's folder would be (the same
scenario as run, or it is run again), and returns the rows as
``sweep.run_sweeps`` does. What a run in one process cannot have is what
depends on processes' timing: its lockstep misses are 0 by construction,
its ``ticks_per_s`` is the engine's.
"""

from __future__ import annotations

import json
import signal
import sys
import time
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from formation_swarm.studies.jobs import Job
from formation_swarm.studies.sweep import Sweep, unfit_runs
from formation_swarm.studies.tables import metrics, write_csv


class EngineSweep(Sweep):
    """A sweep whose runs are stepped in this process (``run_all``)."""

    def task(self, job: Job) -> tuple[str, int, dict[str, Any], list[str], bool]:
        return (str(self.scenario), job.seed, dict(job.overrides), list(map(str, self.faults)), self.logger)

    def run(self) -> list[dict[str, Any]]:
        return run_all({"": self}, workers=self.workers)[""]


def row_of(task: tuple[str, int, dict[str, Any], list[str], bool]) -> dict[str, Any]:
    """One run's metrics; the EKF's target errors only where a lockstep run would have a logger."""
    from formation_swarm.studies import engine_run

    scenario, seed, overrides, faults, logger = task
    summary, _vn = engine_run.run(scenario, seed, overrides, faults)
    if not logger:
        summary["parts"].pop("logger", None)
    return {"trajectory_digest": summary["trajectory_digest"], **metrics(summary)}


def _ignore_stop_signals() -> None:
    """In a pool's worker: Ctrl-C and SIGTERM are the sweep's to handle (it stops the pool)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _cached(path: Path) -> dict[str, Any] | None:
    try:
        row = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return row if isinstance(row, dict) and row.get("exit_code") == 0 else None


def run_all(sweeps: Mapping[str, EngineSweep], workers: int | None = None) -> dict[str, list[dict[str, Any]]]:
    """Every sweep's rows in its jobs' order: those kept in its folder read, the others run,
    as many at once as ``workers`` (default: the first sweep's)."""
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    todo: list[tuple[str, Job]] = []
    for name, sw in sweeps.items():
        (sw.out / "runs").mkdir(parents=True, exist_ok=True)
        for job in sw.jobs:
            if (kept := _cached(sw.out / "runs" / f"{job.name}.json")) is not None:
                rows[name, job.name] = kept
            else:
                todo.append((name, job))
    first = next(iter(sweeps.values()))
    n = max(1, workers or first.workers)
    started = time.monotonic()
    if todo:
        first.progress(f"[engine] {len(todo)} runs to do, {len(rows)} kept; {n} at once")
        tasks = [sweeps[name].task(job) for name, job in todo]
        pool = ProcessPoolExecutor(max_workers=n, initializer=_ignore_stop_signals)
        try:
            for i, ((name, job), got) in enumerate(zip(todo, pool.map(row_of, tasks, chunksize=2), strict=True), 1):
                row = {"combination": job.label, "seed": job.seed, "run": job.name, **got}
                path = sweeps[name].out / "runs" / f"{job.name}.json"
                tmp = path.with_name(path.name + ".tmp")
                tmp.write_text(json.dumps(row))
                tmp.replace(path)
                rows[name, job.name] = row
                if i % 25 == 0 or i == len(todo):
                    el = time.monotonic() - started
                    left = el / i * (len(todo) - i)
                    first.progress(f"[engine] {i}/{len(todo)} runs ({el:.0f} s, about {left:.0f} s left)")
        except BaseException:
            # A stop (Ctrl-C, SIGTERM): the runs not begun are dropped, not waited for; finished ones are kept.
            first.progress("[engine] interrupted: finished runs are kept")
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown()
    out = {name: [rows[name, j.name] for j in sw.jobs] for name, sw in sweeps.items()}
    for name, sw in sweeps.items():
        if out[name]:
            write_csv(sw.out / "runs.csv", out[name])
    return out


def run_engine_sweeps(sweeps: Mapping[str, EngineSweep], out: Path) -> dict[str, list[dict[str, Any]]] | None:
    """``sweep.run_sweeps`` for sweeps stepped in this process: every sweep's rows, or None,
    having said why, when a run cannot enter the table (it failed)."""
    rows = run_all(sweeps)
    unfit = [why for r in rows.values() for why in unfit_runs(r)]
    if unfit:
        print(
            f"swarm results: {len(unfit)} runs cannot enter the table (they failed; run them with swarm run "
            f"to see why), in {out}:\n  " + "\n  ".join(unfit[:10]),
            file=sys.stderr,
        )
        return None
    return rows
