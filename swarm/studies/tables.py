"""A sweep's tables: one row of metrics per run (runs.csv) and, per
combination, the mean, standard deviation and 95% confidence interval
(Student t) of every metric (aggregate.csv); a run's row in brief for a
progress line.
"""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

# 97.5% quantile of Student's t for n - 1 degrees of freedom (n <= 31), then normal.
_T975 = (
    12.706,
    4.303,
    3.182,
    2.776,
    2.571,
    2.447,
    2.365,
    2.306,
    2.262,
    2.228,
    2.201,
    2.179,
    2.160,
    2.145,
    2.131,
    2.120,
    2.110,
    2.101,
    2.093,
    2.086,
    2.080,
    2.074,
    2.069,
    2.064,
    2.060,
    2.056,
    2.052,
    2.048,
    2.045,
    2.042,
)


def metrics(summary: Mapping[str, Any]) -> dict[str, Any]:
    """The flat row of one run's summary: what the sweep tables hold."""
    row: dict[str, Any] = {
        "exit_code": summary.get("exit_code"),
        "ticks": summary.get("ticks"),
        "min_distance_m": summary.get("min_distance_m"),
        "collisions": summary.get("collisions"),
        "obstacle_collisions": summary.get("obstacle_collisions"),
        "lockstep_misses": summary.get("lockstep_misses"),
        "drops": summary.get("drops_total"),
        "rejected": summary.get("rejected_total"),
        "ticks_per_s": summary.get("ticks_per_s"),
    }
    for rid, m in sorted(summary.get("followers", {}).items(), key=_by_robot):
        for k in ("rms_m", "max_m", "turn_rms_m", "straight_rms_m", "turn_mean_lag_m", "max_lag_m", "max_ahead_m"):
            row[f"r{rid}_{k}"] = m.get(k)
    errs = summary.get("parts", {}).get("logger", {}).get("target_errors", {})
    for rid, e in sorted(errs.items(), key=_by_robot):
        row[f"r{rid}_measured_rms_m"] = e.get("measured_rms_m")
        row[f"r{rid}_ekf_rms_m"] = e.get("ekf_rms_m")
        if e.get("measured_rms_m") and e.get("ekf_rms_m") is not None:
            row[f"r{rid}_ekf_ratio"] = e["ekf_rms_m"] / e["measured_rms_m"]
    # The leader's largest distance from its path, and from its last waypoint at the end (world.leader_track).
    path = summary.get("parts", {}).get("world", {}).get("leader_path") or {}
    row["leader_off_path_m"] = path.get("max_off_path_m")
    row["leader_end_m"] = path.get("end_from_last_waypoint_m")
    seq: dict[int, list[str]] = {}
    for ev in summary.get("formation_events", []):
        seq.setdefault(ev["robot"], []).append(ev["formation"])
    for rid, names in sorted(seq.items()):
        row[f"r{rid}_formations"] = ">".join(names)
    return row


def _by_robot(kv: tuple[Any, Any]) -> tuple[int, str]:
    """A summary's per-robot entry in robot order (its JSON keys are text: R10 would come before R2)."""
    key = str(kv[0])
    return (int(key), key) if key.isdigit() else (1 << 62, key)


def t975(n: int) -> float:
    """The 97.5% quantile of Student's t for the mean of ``n`` >= 2 values (the normal's beyond 31)."""
    return _T975[n - 2] if n - 2 < len(_T975) else 1.96


def half_width(vals: Sequence[float]) -> float:
    """The 95% confidence half-width of the mean of ``vals`` (Student t); nan for fewer than two."""
    n = len(vals)
    return t975(n) * statistics.stdev(vals) / math.sqrt(n) if n > 1 else math.nan


def aggregate(rows: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per combination and numeric metric: n, mean, std and the 95% CI of the mean."""
    by_label: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        by_label.setdefault(r["combination"], []).append(r)
    out = []
    for label, group in by_label.items():
        keys = [k for k in group[0] if k not in ("combination", "seed", "run")]
        for k in keys:
            vals = [float(r[k]) for r in group if _is_number(r.get(k))]
            vals = [v for v in vals if math.isfinite(v)]
            if not vals:
                continue
            n = len(vals)
            mean = statistics.fmean(vals)
            std = statistics.stdev(vals) if n > 1 else 0.0
            half = half_width(vals)
            out.append(
                {
                    "combination": label,
                    "metric": k,
                    "n": n,
                    "mean": mean,
                    "std": std,
                    "ci95_low": mean - half,
                    "ci95_high": mean + half,
                    "min": min(vals),
                    "max": max(vals),
                }
            )
    return out


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    tmp = path.with_suffix(".csv.tmp")
    with tmp.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        w.writerows(rows)
    tmp.replace(path)  # never a half-written table


BRIEF_FOLLOWERS = 4  # beyond, a progress line gives the followers' median and worst RMS, not each


def brief_rms(row: Mapping[str, Any]) -> tuple[tuple[str, float], ...]:
    """The followers' RMS (m) of a run's row for its progress line: (follower
    number, RMS) each, in the row's order, those with a number only."""
    return tuple(
        (k[1:-6], float(row[k])) for k in row if k.endswith("_rms_m") and k.count("_") == 2 and _is_number(row[k])
    )


def brief(row: Mapping[str, Any]) -> str:
    """A run's row for a progress line: each follower's RMS (``brief_rms``), or
    beyond BRIEF_FOLLOWERS their median and the worst."""
    rms = brief_rms(row)
    if len(rms) > BRIEF_FOLLOWERS:
        values = sorted(v for _, v in rms)
        worst = max(rms, key=lambda kv: kv[1])
        return (
            f"{len(rms)} followers' RMS: median {statistics.median(values):.2f} m, worst {worst[1]:.2f} m (R{worst[0]})"
        )
    return ", ".join(f"r{rid}_rms {v:.2f} m" for rid, v in rms) or "no follower metrics"


# The final table's columns beside the followers' RMS: (metric, heading, format).
TABLE_METRICS = (
    ("min_distance_m", "min distance m", ".2f"),
    ("collisions", "collisions", ".1f"),
    ("lockstep_misses", "lockstep misses", ".1f"),
)


def summary_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """The sweep's result at a glance, a line per combination: its runs and
    the mean and 95% confidence half-width over its seeds of each follower's
    formation error RMS (beyond BRIEF_FOLLOWERS, the followers' median and
    worst mean) and of the least distance, collisions and lockstep misses.
    Every metric: aggregate.csv."""
    stats = {(a["combination"], a["metric"]): a for a in aggregate(rows)}
    labels = list(dict.fromkeys(r["combination"] for r in rows))
    followers = sorted(
        {k[1:-6] for r in rows for k in r if k.endswith("_rms_m") and k.count("_") == 2},
        key=lambda rid: (int(rid), rid) if rid.isdigit() else (1 << 62, rid),
    )

    def cell(label: str, metric: str, fmt: str = ".3f") -> str:
        a = stats.get((label, metric))
        if a is None:
            return "-"
        half = (a["ci95_high"] - a["ci95_low"]) / 2
        return f"{a['mean']:{fmt}}" + (f" ± {half:{fmt}}" if math.isfinite(half) else "")

    head = ["combination", "runs"]
    if len(followers) <= BRIEF_FOLLOWERS:
        head += [f"R{rid} RMS m" for rid in followers]
    else:
        head += [f"RMS m: median of {len(followers)}", "worst follower"]
    head += [h for _, h, _ in TABLE_METRICS]
    lines = [head]
    for label in labels:
        runs = sum(r["combination"] == label for r in rows)
        line = [label or "as shipped", str(runs)]
        if len(followers) <= BRIEF_FOLLOWERS:
            line += [cell(label, f"r{rid}_rms_m") for rid in followers]
        else:
            line += _many_rms(stats, label, followers)
        line += [cell(label, metric, fmt) for metric, _, fmt in TABLE_METRICS]
        lines.append(line)
    widths = [max(len(line[i]) for line in lines) for i in range(len(head))]
    return "\n".join("  ".join(c.ljust(wd) for c, wd in zip(line, widths, strict=True)).rstrip() for line in lines)


def _many_rms(stats: Mapping[tuple[str, str], Mapping[str, Any]], label: str, followers: list[str]) -> list[str]:
    """The followers' mean RMS over the seeds: their median, and the worst one's."""
    means = [(stats[(label, f"r{rid}_rms_m")]["mean"], rid) for rid in followers if (label, f"r{rid}_rms_m") in stats]
    if not means:
        return ["-", "-"]
    worst = max(means)
    return [f"{statistics.median(m for m, _ in means):.3f}", f"R{worst[1]} {worst[0]:.3f}"]
