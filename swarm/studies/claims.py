"""The paper's claims a-d measured over seeds, under chosen scenario settings
(``swarm results --claims --set robot.wheel_noise_mps=0.1``).

The claims and their criteria are those of tests/system/test_claims.py (the claims
themselves, not fitted margins); here they are evaluated seed by seed and
said in a table: the figures (min-max over the seeds) and in how many seeds
each holds. Claim d is judged on the paper's Fig. 11 run. A rank that swaps
sides (``fig11_rank_swap``, a scenario of ours, not the paper's) is where
eq. 11-13 decide a contact: ``rank_swap`` states it for the avoidance's
section, and both runs are flown without them too (``avoidance_table``, the
ablation). Nothing here runs anything: ``SWEEPS`` names the runs, ``table``
reads their rows.
"""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Source:
    """The runs a claim is measured on: a shipped scenario, whether the logger
    records them (for the EKF's and the raw target errors), and scenario keys
    of their own, which put them in a folder of their own (``tag``)."""

    file: str
    logger: bool = False
    overrides: Mapping[str, Any] = field(default_factory=dict)
    tag: str = ""

    @property
    def folder(self) -> str:
        return Path(self.file).stem + (f"-{self.tag}" if self.tag else "")


# Eq. 11-13 skipped: a follower goes straight to its new slot (claim d's ablation).
NO_AVOIDANCE = {"controller.avoidance": False}
# What each claim is measured on, by sweep name.
SWEEPS: dict[str, Source] = {
    "static 1.5": Source("fig6_turn_vn_1_5.toml"),
    "static 2": Source("fig6_turn_vn_2.toml"),
    "dynamic": Source("fig7_turn_vn_dynamic.toml"),
    "ekf": Source("fig9_ekf_noise.toml", logger=True),
    "obstacles": Source("fig11_obstacles.toml"),
    "obstacles, no avoidance": Source("fig11_obstacles.toml", overrides=NO_AVOIDANCE, tag="no-avoidance"),
    # Not the paper's: a rank that swaps sides behind its references, for the avoidance's section
    # (eq. 11-13 keep it apart, and without them it touches).
    "rank swap": Source("fig11_rank_swap.toml"),
    "rank swap, no avoidance": Source("fig11_rank_swap.toml", overrides=NO_AVOIDANCE, tag="no-avoidance"),
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


def _clear(r: Mapping[str, Any]) -> bool:
    """No contact, between robots or with an obstacle, and never closer than a robot's diameter."""
    return r["collisions"] == 0 and r["obstacle_collisions"] == 0 and r["min_distance_m"] > 0.4


def _changes(r: Mapping[str, Any], sequence: str) -> bool:
    """Every robot of the three flew these formations, in this order."""
    return [r.get(f"r{i}_formations") for i in (1, 2, 3)] == [sequence] * 3


def _switched_clear(runs: Sequence[Mapping[str, Any]], sequence: str) -> tuple[int, int, str]:
    """Of these runs: how many flew ``sequence``, how many also touched nothing,
    and the contacts and closest approach, said."""
    n = len(runs)
    changed = _count(n, lambda i: _changes(runs[i], sequence))
    ok = _count(n, lambda i: _changes(runs[i], sequence) and _clear(runs[i]))
    said = (
        f"{sum(r['collisions'] for r in runs)} collisions between robots, "
        f"{sum(r['obstacle_collisions'] for r in runs)} with obstacles; minimum distance "
        f"{min(r['min_distance_m'] for r in runs):.2f} m"
    )
    return changed, ok, said


def claim_d(rows: Rows) -> Claim:
    obs = rows["obstacles"]
    n = len(obs)
    changed, ok, said = _switched_clear(obs, "line>triangle")
    text = (
        f"`fig11_obstacles`: every robot line then triangle in {changed} of {n} "
        f"seeds; {said} (diameter 0.4 m). R3's max error {_m(obs, 'r3_max_m')}."
    )
    return Claim("d. the obstacle run goes triangle, line, triangle, no collision", text, ok, n)


def rank_swap(rows: Rows) -> Claim:
    """The avoidance's statement on the rank swap, a scenario of ours where eq. 11-13
    decide a contact: judged on the runs with them; the same seeds without them
    (the ablation) say that they do. Not one of the paper's claims."""
    swap, off = rows["rank swap"], rows["rank swap, no avoidance"]
    n = len(swap)
    changed, ok, said = _switched_clear(swap, "rank_left>rank_right")
    text = (
        f"`fig11_rank_swap`: every robot to the left and back in {changed} of {n} seeds; "
        f"{said}. Without eq. 11-13 (`controller.avoidance = false`): "
        f"two robots touch in {sum(1 for r in off if r['collisions'])} of {len(off)} seeds "
        f"({sum(r['collisions'] for r in off)} contacts), minimum distance "
        f"{min(r['min_distance_m'] for r in off):.2f} m."
    )
    return Claim("with eq. 11-13 the rank swaps sides and back without contact", text, ok, n)


# The paper's claims a-d.
CLAIMS = (claim_a, claim_b_behind, claim_b_overshoot, claim_c, claim_d)


def measure(rows: Rows) -> list[Claim]:
    return [c(rows) for c in CLAIMS]


def table(rows: Rows, settings: str) -> str:
    n = len(rows["dynamic"])
    lines = [
        f"The paper's claims with {settings or 'the scenarios as shipped'}: seeds 0-{n - 1}, runs in one "
        "process (`formation_swarm.engine`); "
        "the criteria of tests/system/test_claims.py, evaluated seed by seed.",
        "",
        f"| claim | measured (min-max over {n} seeds; mean ± 95% confidence half-width) | holds |",
        "|---|---|---|",
    ]
    lines += [f"| {c.name} | {c.measured} | {c.verdict} |" for c in measure(rows)]
    return "\n".join(lines)


# Claim d's ablation: (scenario, eq. 11-13, sweep), the rows of avoidance_table.
ABLATION = (
    ("fig11_obstacles", "on (as shipped)", "obstacles"),
    ("fig11_obstacles", "off", "obstacles, no avoidance"),
    ("fig11_rank_swap", "on (as shipped)", "rank swap"),
    ("fig11_rank_swap", "off", "rank swap, no avoidance"),
)


def avoidance_table(rows: Rows) -> str:
    """Claim d's ablation: its runs with and without eq. 11-13, seed for seed, and what that says."""
    n = len(rows["rank swap"])
    lines = [
        f"Seeds 0-{n - 1}, runs in one process (`formation_swarm.engine`), with the partition-zone "
        "avoidance (eq. 11-13) and without it "
        "(`controller.avoidance = false`: a follower goes straight to its new slot); robots are 0.4 m "
        "across, closer than that they touch.",
        "",
        "| scenario | eq. 11-13 | seeds in which two robots touch | contacts between robots "
        "| contacts with obstacles | closest approach of two robots' centres, min-max (median), m |",
        "|---|---|---|---|---|---|",
    ]
    for scenario, label, name in ABLATION:
        runs = rows[name]
        closest = [float(r["min_distance_m"]) for r in runs]
        lines.append(
            f"| `{scenario}` | {label} | {_touched(runs)} of {len(runs)} "
            f"| {sum(r['collisions'] for r in runs)} | {sum(r['obstacle_collisions'] for r in runs)} "
            f"| {min(closest):.3f}-{max(closest):.3f} ({statistics.median(closest):.3f}) |"
        )
    lines += ["", *(f"- {_ablation_said(scenario, rows)}" for scenario, _label, _name in ABLATION[::2])]
    return "\n".join(lines)


def _touched(runs: Sequence[Mapping[str, Any]]) -> int:
    """The runs in which two robots touched."""
    return sum(1 for r in runs if r["collisions"])


def _ablation_said(scenario: str, rows: Rows) -> str:
    """What the ablation of one scenario says of eq. 11-13, from its two rows."""
    on, off = (rows[name] for s, _label, name in ABLATION if s == scenario)
    k_on, k_off, n = _touched(on), _touched(off), len(on)
    if k_off == 0:
        return (
            f"`{scenario}`: no two robots touch in any of the {n} seeds, with eq. 11-13 or without them; "
            "the avoidance is not what keeps them apart there."
        )
    said = f"`{scenario}`: two robots touch in {k_off} of {n} seeds without eq. 11-13 and in {k_on} with them"
    return said + ("; the avoidance is what keeps them apart." if k_on == 0 else ".")


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
                row[k] = number(v)
            out.setdefault(r["sweep"], []).append(row)
    for runs in out.values():
        runs.sort(key=lambda r: r["seed"])
    return out


def number(text: str) -> Any:
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
