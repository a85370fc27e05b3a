"""The margins study's tables, from its rows (studies.margins.runs): each
figure a mean over seeds with its 95% confidence half-width (Student t)."""

from __future__ import annotations

import statistics
from collections import defaultdict
from collections.abc import Mapping, Sequence
from typing import Any

from scipy.stats import chi2

from formation_swarm.studies.margins import CLAIM_A, DROPS, NEES_ROWS, SPEEDS, drop_group, speed_group
from formation_swarm.studies.tables import half_width
from formation_swarm.world.metrics import NEES_TICK_BOUND_99

Rows = Sequence[Mapping[str, Any]]


def by_group(rows: Rows) -> dict[str, list[Mapping[str, Any]]]:
    out: dict[str, list[Mapping[str, Any]]] = defaultdict(list)
    for r in rows:
        out[r["group"]].append(r)
    for runs in out.values():
        runs.sort(key=lambda r: r["seed"])
    return out


def interval(vals: Sequence[float]) -> tuple[float, float, float]:
    """Mean, and the 95% interval's low and high ends."""
    m, h = statistics.fmean(vals), half_width(vals)
    return m, m - h, m + h


def verdict(lo: float, hi: float, threshold: str = "zero") -> str:
    """Where the interval of a margin (claim's quantity minus its threshold; < 0: holds) lies."""
    return "holds" if hi < 0 else "fails" if lo > 0 else f"not decided: the interval spans {threshold}"


def claim_a_margins(rows: Rows, speed: float) -> dict[str, list[float]]:
    """Per seed at ``speed``: dynamic V_N's max and RMS error minus the better static V_N's."""
    g = by_group(rows)
    dyn, s15, s2 = (g[speed_group(name, speed)] for name in CLAIM_A)
    out: dict[str, list[float]] = {"max": [], "rms": []}
    for d, a, b in zip(dyn, s15, s2, strict=True):
        if not d["seed"] == a["seed"] == b["seed"]:
            raise ValueError(f"claim a at {speed:g} m/s: seeds {d['seed']}, {a['seed']}, {b['seed']} do not match")
        out["max"].append(d["r2_max_m"] - min(a["r2_max_m"], b["r2_max_m"]))
        out["rms"].append(d["r2_rms_m"] - min(a["r2_rms_m"], b["r2_rms_m"]))
    return out


def _cell(vals: Sequence[float]) -> str:
    m, lo, hi = interval(vals)
    return f"{m:+.3f} [{lo:+.3f}, {hi:+.3f}]"


def claim_a_table(rows: Rows) -> str:
    n = len(by_group(rows)[speed_group("dynamic", SPEEDS[0])])
    lines = [
        f"Claim a as a margin: follower R2's error with dynamic V_N minus the lower of static V_N 1.5's and 2's, "
        f"seed by seed (< 0: dynamic is better); mean [95% interval] over seeds 0-{n - 1}, runs in one process "
        "(`formation_swarm.engine`).",
        "",
        "| leader speed | max error margin, m | RMS error margin, m | seeds where both < 0 | claim a |",
        "|---|---|---|---|---|",
    ]
    holds = []
    for v in SPEEDS:
        m = claim_a_margins(rows, v)
        both = sum(1 for a, b in zip(m["max"], m["rms"], strict=True) if a < 0 and b < 0)
        ends = [interval(m[k])[1:] for k in ("max", "rms")]
        said = verdict(max(lo for lo, _ in ends), max(hi for _, hi in ends))  # holds: both below zero
        holds += [v] if said == "holds" else []
        lines.append(f"| {v:g} m/s | {_cell(m['max'])} | {_cell(m['rms'])} | {both}/{n} | {said} |")
    lines += ["", f"Claim a's band, where both intervals lie below zero: {_speeds(holds)}."]
    return "\n".join(lines)


def _speeds(vals: Sequence[float]) -> str:
    if not vals:
        return "no speed tried"
    return f"{vals[0]:g}-{vals[-1]:g} m/s" if len(vals) > 1 else f"{vals[0]:g} m/s"


def claim_c_table(rows: Rows) -> str:
    g = by_group(rows)
    n = len(g[drop_group(0.0)])
    lines = [
        "Claim c on matching ticks: the EKF's target error RMS over the raw reading's, both on the ticks with a "
        "reading, beside the ratio of tests/system/test_claims.py (the EKF's over every tick, predictions "
        f"included); `fig9_ekf_noise`, mean [95% interval] over seeds 0-{n - 1}; the claim holds where the "
        "interval lies below 0.5.",
        "",
        "| observation drops | ratio on matching ticks | claim c, matching ticks | ratio over every tick (criterion) "
        "| claim c, criterion |",
        "|---|---|---|---|---|",
    ]
    for d in DROPS:
        runs = g[drop_group(d)]
        seen = [r["r2_ekf_rms_seen_m"] / r["r2_measured_rms_m"] for r in runs]
        every = [r["r2_ekf_rms_m"] / r["r2_measured_rms_m"] for r in runs]
        cells = []
        for vals in (seen, every):
            m, lo, hi = interval(vals)
            cells += [f"{m:.3f} [{lo:.3f}, {hi:.3f}]", verdict(lo - 0.5, hi - 0.5, "0.5")]
        lines.append(f"| {d:.0%} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def nees_bound(ticks: float) -> float:
    """The 99% point of a consistent filter's mean NEES over ``ticks`` independent ticks: chi2(2 n) / n."""
    n = max(1, round(ticks))
    return float(chi2.ppf(0.99, 2 * n) / n)


def nees_table(rows: Rows) -> str:
    g = by_group(rows)
    n = len(g[NEES_ROWS[0][1]])
    lines = [
        "The EKF's NEES of follower R2's target (x, y) on `fig9_ekf_noise`: e' P^-1 e every tick with an "
        "estimate, 2 on average for a consistent filter. Mean over the run, then mean [95% interval] over seeds "
        f"0-{n - 1}; the bound is the 99% point of a consistent filter's mean over the run's ticks, "
        "chi-square(2n)/n, which treats the ticks as independent (they are not: it is a tight bound); "
        f"beyond {NEES_TICK_BOUND_99:g}, chi-square(2)'s 99% point, a consistent filter has 1% of its ticks.",
        "",
        "| filter, setting | mean NEES | min-max over seeds | ticks beyond 9.21 | bound on the mean | seeds above it |",
        "|---|---|---|---|---|---|",
    ]
    for label, group in NEES_ROWS:
        runs = g[group]
        nees = [r["r2_nees_mean"] for r in runs]
        m, lo, hi = interval(nees)
        bound = nees_bound(statistics.fmean(r["r2_nees_ticks"] for r in runs))
        beyond = statistics.fmean(r["r2_nees_beyond_99"] for r in runs)
        above = sum(1 for x in nees if x > bound)
        lines.append(
            f"| {label} | {m:.2f} [{lo:.2f}, {hi:.2f}] | {min(nees):.2f}-{max(nees):.2f} | {beyond:.1%} "
            f"| {bound:.2f} | {above}/{n} |"
        )
    return "\n".join(lines)
