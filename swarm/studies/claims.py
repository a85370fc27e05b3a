"""The paper's claims a-d measured over seeds, under chosen scenario settings
(``swarm results --claims --set robot.wheel_noise_mps=0.1``).

The claims and their criteria are those of tests/unit/studies/test_claims.py (the claims
themselves, not fitted margins); here they are evaluated seed by seed and
said in a table: the figures (min-max over the seeds) and in how many seeds
each holds. Nothing here runs anything: ``plan`` names the sweeps, ``table``
reads their rows.
"""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

# What each claim is measured on: (sweep name, scenario file, needs the logger).
SWEEPS: dict[str, tuple[str, bool]] = {
    "static 1.5": ("fig6_turn_vn_1_5.toml", False),
    "static 2": ("fig6_turn_vn_2.toml", False),
    "dynamic": ("fig7_turn_vn_dynamic.toml", False),
    "ekf": ("fig9_ekf_noise.toml", True),  # the EKF's and the raw target errors come from the recording
    "obstacles": ("fig11_obstacles.toml", False),
}

Rows = Mapping[str, Sequence[Mapping[str, Any]]]  # sweep name -> one row per seed, in seed order


@dataclass(frozen=True)
class Claim:
    name: str
    measured: str
    holds: int  # seeds in which it holds
    seeds: int

    @property
    def verdict(self) -> str:
        if self.holds == self.seeds:
            return "yes"
        if self.holds == 0:
            return "no"
        return f"in {self.holds} of {self.seeds} seeds"


def _span(rows: Sequence[Mapping[str, Any]], key: str, fmt: str = ".3f", sign: str = "", unit: str = "") -> str:
    """``"0.706-0.746 m"``: the smallest and the largest value over the seeds."""
    vals = [float(r[key]) for r in rows]
    lo, hi = f"{min(vals):{sign}{fmt}}", f"{max(vals):{fmt}}"
    sep = " to " if min(vals) < 0 else "-"
    text = lo if f"{min(vals):{fmt}}" == hi else f"{lo}{sep}{hi}"
    return f"{text} {unit}".rstrip()


def _m(rows: Sequence[Mapping[str, Any]], key: str, sign: str = "") -> str:
    return _span(rows, key, sign=sign, unit="m")


def _ci(rows: Sequence[Mapping[str, Any]], key: str, fmt: str = ".3f") -> str:
    """``"mean 0.727 ± 0.004"``: the mean over the seeds and its 95% confidence half-width (Student t)."""
    from formation_swarm.studies.tables import half_width

    vals = [float(r[key]) for r in rows]
    mean, half = statistics.fmean(vals), half_width(vals)
    return f"mean {mean:{fmt}}" if math.isnan(half) else f"mean {mean:{fmt}} ± {half:{fmt}}"


def _count(n: int, test: Callable[[int], bool]) -> int:
    return sum(1 for i in range(n) if test(i))


def claim_a(rows: Rows) -> Claim:
    dyn, s15, s2 = rows["dynamic"], rows["static 1.5"], rows["static 2"]
    n = len(dyn)
    ok = _count(n, lambda i: all(dyn[i][k] < other[i][k] for other in (s15, s2) for k in ("r2_rms_m", "r2_max_m")))
    text = (
        f"RMS: dynamic {_m(dyn, 'r2_rms_m')} ({_ci(dyn, 'r2_rms_m')}), static 1.5 {_m(s15, 'r2_rms_m')} "
        f"({_ci(s15, 'r2_rms_m')}), static 2 {_m(s2, 'r2_rms_m')} ({_ci(s2, 'r2_rms_m')}). "
        f"Max: dynamic {_m(dyn, 'r2_max_m')}, static 1.5 {_m(s15, 'r2_max_m')}, static 2 {_m(s2, 'r2_max_m')}. "
        f"Both lower in {ok} of {n} seeds."
    )
    return Claim("a. dynamic V_N has lower RMS and max error than static 1.5 and 2", text, ok, n)


def claim_b_behind(rows: Rows) -> Claim:
    s15 = rows["static 1.5"]
    n = len(s15)
    is_behind = [r["r2_turn_rms_m"] > r["r2_straight_rms_m"] and r["r2_turn_mean_lag_m"] > 0.5 for r in s15]
    is_never_ahead = [r["r2_max_ahead_m"] == 0.0 for r in s15]
    behind, never_ahead = sum(is_behind), sum(is_never_ahead)
    ok = sum(b and a for b, a in zip(is_behind, is_never_ahead, strict=True))
    text = (
        f"RMS in turns {_m(s15, 'r2_turn_rms_m')} vs {_m(s15, 'r2_straight_rms_m')} on straights; mean lag in "
        f"turns {_m(s15, 'r2_turn_mean_lag_m', '+')} ({_ci(s15, 'r2_turn_mean_lag_m')}): behind in {behind} "
        f"of {n} seeds. Never ahead of its "
        f"target in {never_ahead} of {n} seeds (ahead by up to {_m(s15, 'r2_max_ahead_m')})."
    )
    return Claim("b. static 1.5 falls behind in the turns", text, ok, n)


def claim_b_overshoot(rows: Rows) -> Claim:
    s2, s15, dyn = rows["static 2"], rows["static 1.5"], rows["dynamic"]
    n = len(s2)
    ok = _count(
        n,
        lambda i: (
            s2[i]["r2_max_ahead_m"] > 0.25
            and s2[i]["r2_max_ahead_m"] > s15[i]["r2_max_ahead_m"]
            and s2[i]["r2_max_ahead_m"] > dyn[i]["r2_max_ahead_m"]
        ),
    )
    text = (
        f"gets {_m(s2, 'r2_max_ahead_m')} ({_ci(s2, 'r2_max_ahead_m')}) ahead of its target (static 1.5 "
        f"{_m(s15, 'r2_max_ahead_m')}, dynamic "
        f"{_m(dyn, 'r2_max_ahead_m')}); more than 0.25 m and than both in {ok} of {n} seeds. Mean lag in turns "
        f"{_m(s2, 'r2_turn_mean_lag_m', '+')}; RMS on straights {_m(s2, 'r2_straight_rms_m')}."
    )
    return Claim("b. static 2 overshoots", text, ok, n)


def claim_c(rows: Rows) -> Claim:
    ekf = rows["ekf"]
    n = len(ekf)
    ok = _count(n, lambda i: ekf[i]["r2_ekf_rms_m"] <= 0.5 * ekf[i]["r2_measured_rms_m"])
    text = (
        f"`fig9_ekf_noise`: EKF RMS {_m(ekf, 'r2_ekf_rms_m')} vs measured {_m(ekf, 'r2_measured_rms_m')}, "
        f"ratio {_span(ekf, 'r2_ekf_ratio', '.2f')} ({_ci(ekf, 'r2_ekf_ratio')}); at most half in {ok} of {n} seeds."
    )
    return Claim("c. the EKF's target error is at most half the raw error", text, ok, n)


def claim_d(rows: Rows) -> Claim:
    obs = rows["obstacles"]
    n = len(obs)

    def changes(r: Mapping[str, Any]) -> bool:
        return [r.get(f"r{i}_formations") for i in (1, 2, 3)] == ["line>triangle"] * 3

    def clear(r: Mapping[str, Any]) -> bool:
        return r["collisions"] == 0 and r["obstacle_collisions"] == 0 and r["min_distance_m"] > 0.4

    ok = _count(n, lambda i: changes(obs[i]) and clear(obs[i]))
    text = (
        f"`fig11_obstacles`: every robot line then triangle in {_count(n, lambda i: changes(obs[i]))} of {n} "
        f"seeds; {sum(r['collisions'] for r in obs)} collisions between robots, "
        f"{sum(r['obstacle_collisions'] for r in obs)} with obstacles; minimum distance "
        f"{min(r['min_distance_m'] for r in obs):.2f} m (diameter 0.4 m). R3's max error {_m(obs, 'r3_max_m')}."
    )
    return Claim("d. the obstacle run goes triangle, line, triangle, no collision", text, ok, n)


CLAIMS = (claim_a, claim_b_behind, claim_b_overshoot, claim_c, claim_d)


def measure(rows: Rows) -> list[Claim]:
    return [c(rows) for c in CLAIMS]


def table(rows: Rows, settings: str) -> str:
    n = len(rows["dynamic"])
    lines = [
        f"The paper's claims with {settings or 'the scenarios as shipped'}: lockstep runs, seeds 0-{n - 1}; "
        "the criteria of tests/unit/studies/test_claims.py, evaluated seed by seed.",
        "",
        f"| claim | measured (min-max over {n} seeds; mean ± 95% confidence half-width) | holds |",
        "|---|---|---|",
    ]
    lines += [f"| {c.name} | {c.measured} | {c.verdict} |" for c in measure(rows)]
    return "\n".join(lines)


def write_rows(path: Path, rows: Rows) -> None:
    """Every run's row, named by its sweep, into a CSV (written whole, then moved into place)."""
    flat = [{"sweep": name, **r} for name, runs in rows.items() for r in runs]
    cols: list[str] = []
    for r in flat:
        cols += [k for k in r if k not in cols]
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        w.writerows(flat)
    tmp.replace(path)


def read_rows(path: Path) -> dict[str, list[dict[str, Any]]]:
    """``write_rows``'s CSV back, numbers as numbers, per sweep in seed order."""
    out: dict[str, list[dict[str, Any]]] = {}
    with path.open(newline="") as f:
        for r in csv.DictReader(f):
            row: dict[str, Any] = {}
            for k, v in r.items():
                if k == "sweep" or v is None:
                    continue
                row[k] = _number(v)
            out.setdefault(r["sweep"], []).append(row)
    for runs in out.values():
        runs.sort(key=lambda r: r["seed"])
    return out


def _number(text: str) -> Any:
    if text == "":
        return None
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text
