"""The sensitivity study's runs as rows of a CSV (``swarm results --sensitivity
--rows docs/results/sensitivity.csv``): one per run, named by its axis, value
and sweep, with the metrics the claims and the sections read, every digit of
them. The axes run replace their own rows and keep the others', so that the
summary of every claim along every axis is made from the whole file.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from formation_swarm.studies import claims

# What the claims (formation_swarm.studies.claims) and the sections read of a run, and whether it is fit.
COLUMNS = (
    "seed",
    "exit_code",
    "lockstep_misses",
    "min_distance_m",
    "collisions",
    "obstacle_collisions",
    "r2_rms_m",
    "r2_max_m",
    "r2_turn_rms_m",
    "r2_straight_rms_m",
    "r2_turn_mean_lag_m",
    "r2_max_ahead_m",
    "r2_measured_rms_m",
    "r2_ekf_rms_m",
    "r2_ekf_ratio",
    "r3_max_m",
    "r1_formations",
    "r2_formations",
    "r3_formations",
    "leader_off_path_m",
    "leader_end_m",
)
# axis name -> value -> the point's rows (sweep name -> one row per seed)
Table = dict[str, dict[float, dict[str, list[dict[str, Any]]]]]


def read(path: Path) -> Table:
    """The file's rows, numbers as numbers, per axis, value and sweep, in seed order; {} without a file."""
    out: Table = {}
    if not path.exists():
        return out
    with path.open(newline="") as f:
        for r in csv.DictReader(f):
            row = {k: claims.number(v) for k, v in r.items() if k in COLUMNS and v is not None}
            point = out.setdefault(r["axis"], {}).setdefault(float(r["value"]), {})
            point.setdefault(r["sweep"], []).append(row)
    for points in out.values():
        for rows in points.values():
            for runs in rows.values():
                runs.sort(key=lambda r: r["seed"])
    return out


def write(path: Path, table: Mapping[str, Mapping[float, claims.Rows]]) -> None:
    """Every row of ``table`` into the CSV (written whole, then moved into place)."""
    fields = ["axis", "value", "sweep", *COLUMNS]
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for axis, points in table.items():
            for value, rows in points.items():
                for sweep, runs in rows.items():
                    w.writerows({"axis": axis, "value": repr(value), "sweep": sweep, **r} for r in runs)
    tmp.replace(path)


def merge(path: Path, axis: str, points: Mapping[float, claims.Rows]) -> Table:
    """The file with ``axis``'s rows replaced by ``points``', written back; the whole table."""
    table = read(path)
    table[axis] = {float(v): {name: list(runs) for name, runs in rows.items()} for v, rows in points.items()}
    write(path, table)
    return table
