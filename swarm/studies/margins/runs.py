"""The runs of the margins study, each in this process (studies.engine_run),
as many at once as asked; each run's row is kept in the study's folder as
JSON, so a second call reuses it (resumable), and every row goes to one CSV.
"""

from __future__ import annotations

import csv
import json
import sys
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from formation_swarm.studies.jobs import Job, slug
from formation_swarm.studies.tables import metrics

ROOT = Path(__file__).resolve().parents[3]
# Where the rows of the EKF's own figures come from: world.metrics.TargetErrors.
TARGET_KEYS = ("ekf_rms_seen_m", "nees_mean", "nees_ticks", "nees_beyond_99")


@dataclass(frozen=True)
class Run:
    """One run: the set it belongs to (a table's row), its scenario, its keys, its seed."""

    group: str
    scenario: str
    overrides: Mapping[str, Any]
    seed: int

    @property
    def name(self) -> str:
        job = Job(self.group, dict(self.overrides), self.seed, context=self.scenario)
        return f"{slug(self.scenario)}-{job.name}"


def row_of(run: Run) -> dict[str, Any]:
    """The run's flat row: the sweep tables' metrics and the EKF's (TARGET_KEYS), per follower."""
    from formation_swarm.studies import engine_run

    summary, _vn = engine_run.run(ROOT / "scenarios" / f"{run.scenario}.toml", run.seed, run.overrides)
    row = {"group": run.group, "scenario": run.scenario, "seed": run.seed, **metrics(summary)}
    row["trajectory_digest"] = summary["trajectory_digest"]
    for rid, e in summary["parts"]["logger"]["target_errors"].items():
        for key in TARGET_KEYS:
            row[f"r{rid}_{key}"] = e.get(key)
    return row


def _cached(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def run_all(runs: Sequence[Run], out: Path, workers: int) -> list[dict[str, Any]]:
    """Every run's row, in the order of ``runs``: those in ``out`` read, the others run."""
    out.mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict[str, Any]] = {}
    todo = []
    for run in runs:
        if (row := _cached(out / f"{run.name}.json")) is not None:
            rows[run.name] = row
        else:
            todo.append(run)
    if todo:
        print(f"margins: {len(todo)} runs to do, {len(rows)} reused from {out}", file=sys.stderr, flush=True)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for i, (run, row) in enumerate(zip(todo, pool.map(row_of, todo, chunksize=4), strict=True), start=1):
            (out / f"{run.name}.json").write_text(json.dumps(row))
            rows[run.name] = row
            if i % 50 == 0 or i == len(todo):
                print(f"margins: {i}/{len(todo)} runs done", file=sys.stderr, flush=True)
    return [rows[run.name] for run in runs]


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """Every row, with the union of their columns in order of first appearance."""
    columns: dict[str, None] = {}
    for row in rows:
        columns.update(dict.fromkeys(row))
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(columns))
        w.writeheader()
        w.writerows(rows)


def read_csv(path: Path) -> list[dict[str, Any]]:
    from formation_swarm.studies.claims import number

    text = ("group", "scenario", "trajectory_digest")
    with path.open(newline="") as fh:
        return [
            {k: v if k in text or k.endswith("_formations") else number(v) for k, v in row.items()}
            for row in csv.DictReader(fh)
        ]
