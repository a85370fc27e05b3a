"""The sensitivity study said in markdown: each axis's section (where each
claim holds, the seeds and the metrics at every value) and the summary of
every claim along every axis ("Where each claim holds" in docs/results.md),
from the points of formation_swarm.studies.sensitivity.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from formation_swarm.studies import claims
from formation_swarm.studies.sensitivity import LINES, METRICS, SHORT, Axis, Point, Stat


def _ranges(axis: Axis, values: Sequence[float]) -> str:
    """``1.5-2 m/s`` for consecutive values of the axis, ``1, 1.5 m/s`` otherwise."""
    idx = sorted(axis.values.index(v) for v in values)
    runs: list[list[int]] = []
    for i in idx:
        if runs and i == runs[-1][-1] + 1:
            runs[-1].append(i)
        else:
            runs.append([i])
    parts = [f"{axis.values[r[0]]:g}" if len(r) == 1 else f"{axis.values[r[0]]:g}-{axis.values[r[-1]]:g}" for r in runs]
    return f"{', '.join(parts)} {axis.unit}".strip()


@dataclass(frozen=True)
class Band:
    """Where something is so along an axis: of the ``tried`` values, those where
    it is so in every seed, those where in some (``(value, seeds where it is
    so, seeds)`` each) and those where in none; ``seeds``: the first value's
    seeds, said with every and none."""

    seeds: int
    tried: int
    every: tuple[float, ...] = ()
    some: tuple[tuple[float, int, int], ...] = ()
    none: tuple[float, ...] = ()


def band_of(counts: Sequence[tuple[float, int, int]]) -> Band:
    """``(value, seeds where it is so, seeds)`` along an axis, as a ``Band``."""
    return Band(
        seeds=counts[0][2],
        tried=len(counts),
        every=tuple(v for v, k, n in counts if k == n),
        some=tuple((v, k, n) for v, k, n in counts if 0 < k < n),
        none=tuple(v for v, k, _n in counts if k == 0),
    )


def say_band(axis: Axis, b: Band, verb: str = "holds") -> str:
    """A ``Band`` said with the seeds: where it is so in every seed, in some
    (each value with its count), in none."""
    seeds = b.seeds
    if len(b.every) == b.tried:
        return f"{verb} in {seeds}/{seeds} seeds at every value tried ({_ranges(axis, b.every)})"
    if len(b.none) == b.tried:
        return f"{verb} in 0/{seeds} seeds at every value tried ({_ranges(axis, b.none)})"
    parts = []
    if b.every:
        parts.append(f"{verb} in {seeds}/{seeds} seeds at {_ranges(axis, b.every)}")
    if b.some:
        said = ", ".join(f"{k}/{n} at {axis.label(v)}" for v, k, n in b.some)
        parts.append(f"in {said}" if b.every else f"{verb} in {said}")
    if b.none:
        parts.append(f"0/{seeds} at {_ranges(axis, b.none)}")
    return "; ".join(parts)


def band(axis: Axis, counts: Sequence[tuple[float, int, int]], verb: str = "holds") -> str:
    """``(value, seeds where it is so, seeds)`` along the axis, said with the seeds
    (``band_of``, ``say_band``)."""
    return say_band(axis, band_of(counts), verb)


def holds(points: Sequence[Point], k: int) -> Band:
    """Where claim ``k`` holds along the points of an axis."""
    return band_of([(p.value, p.claims[k].holds, p.claims[k].seeds) for p in points])


def holds_for(axis: Axis, points: Sequence[Point], k: int) -> str:
    """Claim ``k`` along the axis, with its seeds (``holds``, ``say_band``)."""
    return say_band(axis, holds(points, k))


def touch_without(axis: Axis, points: Sequence[Point], scenario: str) -> str:
    """Claim d's ablation along the axis: where two robots touch without eq. 11-13 (``band``)."""
    return _touch(axis, points, f"{scenario}, no avoidance")


def _touch(axis: Axis, points: Sequence[Point], sweep: str, what: str = "robot", verb: str = "two robots touch") -> str:
    """Where two robots (``what`` "robot") or a robot and an obstacle ("obstacle") touch in the
    runs of ``sweep`` along the axis (``band``)."""
    counts = [(p.value, p.counts[f"{what} contact, {sweep}"], p.counts[f"runs {sweep}"]) for p in points]
    return band(axis, counts, verb)


def _cell(s: Stat | None, fmt: str = ".2f") -> str:
    if s is None or s.n == 0:
        return "-"
    return f"{s.mean:{fmt}}" if math.isnan(s.half) else f"{s.mean:{fmt}} ± {s.half:{fmt}}"


def _row(title: str, cells: Sequence[str]) -> str:
    return f"| {title} | " + " | ".join(cells) + " |"


def _claim_rows(points: Sequence[Point]) -> list[str]:
    """The seeds in which each claim holds, at each value."""
    out = []
    for k in range(len(points[0].claims)):
        short = SHORT[claims.CLAIMS[k].__name__]
        out.append(
            _row(f"claim {short}: seeds where it holds", [f"{p.claims[k].holds}/{p.claims[k].seeds}" for p in points])
        )
    return out


def _metric_rows(points: Sequence[Point]) -> list[str]:
    """The figures' metrics, per controller, at each value."""
    out = []
    for title, key, sweeps, _thr in METRICS:
        for name in sweeps:
            if all((name, key) not in p.stats for p in points):
                continue
            who = LINES.get(name, "fuzzy, dynamic V_N, claim c's run (fig9_ekf_noise)")
            out.append(_row(f"{title.split(' (')[0]}: {who}", [_cell(p.stats.get((name, key))) for p in points]))
    return out


# Claim d's rows: (least distance's sweep, its title), then (count's name, its sweep, its title).
_DISTANCES = (
    ("obstacles", "least distance between two robots' centres, m (claim d, fig11_obstacles; touching below 0.4)"),
    ("obstacles, no avoidance", "the same, fig11_obstacles without eq. 11-13"),
)
_COUNTS = (
    ("obstacle contact, obstacles", "obstacles", "claim d: runs in which a robot touches an obstacle"),
    ("robot contact, obstacles", "obstacles", "claim d: runs in which two robots touch"),
    (
        "robot contact, obstacles, no avoidance",
        "obstacles, no avoidance",
        "fig11_obstacles without eq. 11-13: the same",
    ),
)


def _contact_rows(points: Sequence[Point]) -> list[str]:
    """Claim d's closest approaches and contacts, with and without eq. 11-13."""
    out = [_row(title, [_cell(p.stats.get((name, "min_distance_m"))) for p in points]) for name, title in _DISTANCES]
    for what, name, title in _COUNTS:
        out.append(_row(title, [f"{p.counts.get(what, 0)}/{p.counts.get(f'runs {name}', 0)}" for p in points]))
    return out


def _leader_rows(points: Sequence[Point]) -> list[str]:
    """Where the leader's pilot flies, on the path of claims a-c."""
    return [
        _row(
            "the leader's largest distance from its path, m",
            [_cell(p.stats.get(("dynamic", "leader_off_path_m"))) for p in points],
        ),
        _row(
            "the leader's distance from its last waypoint at the end, m",
            [_cell(p.stats.get(("dynamic", "leader_end_m"))) for p in points],
        ),
    ]


def markdown(axis: Axis, points: Sequence[Point], figure_path: str) -> str:
    """The axis's section: where each claim holds, the table of seeds and the metrics, the figure."""
    seeds = points[0].claims[0].seeds
    lines = [
        f"**{axis.title}** ({axis.note}); seeds 0-{seeds - 1} per value, runs in one process "
        "(`formation_swarm.engine`), the criteria "
        "of tests/system/test_claims.py "
        "evaluated seed by seed; mean ± 95% confidence half-width over the seeds.",
        "",
    ]
    for k, c in enumerate(points[0].claims):
        lines.append(f"- {c.name}: {holds_for(axis, points, k)}.")
    head = " | ".join(axis.label(p.value) + (" (shipped)" if p.value == axis.shipped else "") for p in points)
    lines += ["", f"| | {head} |", "|---" * (len(points) + 1) + "|"]
    lines += _claim_rows(points) + _metric_rows(points) + _contact_rows(points) + _leader_rows(points)
    lines += ["", f"![{axis.title}]({figure_path})"]
    return "\n".join(lines)


# Claim d's ablated sweep: claim function -> the sweep flown without eq. 11-13 too.
ABLATED = {"claim_d": ("obstacles", "fig11_obstacles")}


def where(axes: Mapping[str, tuple[Axis, Sequence[Point]]]) -> str:
    """Every claim along every axis measured (axis name -> its axis and points), in one list."""
    first = next(iter(axes.values()))[1]
    seeds = first[0].claims[0].seeds
    lines = [
        f"From the sensitivity runs below (seeds 0-{seeds - 1} at every value, "
        "`docs/results/sensitivity.csv`); the claims as shipped over 30 seeds are in the next section.",
        "",
    ]
    for k, c in enumerate(first[0].claims):
        lines.append(f"- **{c.name}.**")
        for axis, points in axes.values():
            lines.append(f"  - {axis.title}: {holds_for(axis, points, k)}.")
        if ablated := ABLATED.get(claims.CLAIMS[k].__name__):
            sweep, scenario = ablated
            lines.append(f"  - `{scenario}` without eq. 11-13 (`controller.avoidance = false`), the same seeds:")
            for axis, points in axes.values():
                lines.append(f"    - {axis.title}: {touch_without(axis, points, sweep)}.")
    return "\n".join(lines)


def _swap_band(axis: Axis, points: Sequence[Point]) -> str:
    """Where the rank swap's statement (claims.rank_swap) holds along the axis."""
    counts = [(p.value, p.swap.holds, p.swap.seeds) for p in points if p.swap is not None]
    return band(axis, counts, "swaps without contact")


def _closest(axis: Axis, points: Sequence[Point], sweep: str) -> str:
    """The least distance's mean over the seeds at each value: ``1 m/s 0.36, 1.25 m/s 0.35``."""
    return ", ".join(f"{axis.label(p.value)} {_cell(p.stats.get((sweep, 'min_distance_m')))}" for p in points)


def rank_swap(axes: Mapping[str, tuple[Axis, Sequence[Point]]]) -> str:
    """The rank swap along every axis measured (the avoidance's sensitivity, not a claim of
    the paper): where it swaps without contact with eq. 11-13, where two robots touch
    without them, and the closest approach both ways."""
    first = next(iter(axes.values()))[1]
    seeds = first[0].swap.seeds if first[0].swap is not None else 0
    lines = [
        f"`fig11_rank_swap` at every value of the sensitivity axes (seeds 0-{seeds - 1}, "
        "`docs/results/sensitivity.csv`), with eq. 11-13: every robot to the left and back, no contact, "
        "never closer than a robot's diameter (0.4 m); without them (`controller.avoidance = false`): "
        "where two robots touch. Closest approach of two centres, m: mean ± 95% half-width over the seeds.",
        "",
    ]
    for axis, points in axes.values():
        lines += [
            f"- {axis.title}:",
            f"  - with eq. 11-13: {_swap_band(axis, points)}; {_touch(axis, points, 'rank swap')}; "
            f"{_touch(axis, points, 'rank swap', 'obstacle', 'a robot touches a post')}.",
            f"  - without: {touch_without(axis, points, 'rank swap')}.",
            f"  - closest approach with: {_closest(axis, points, 'rank swap')}.",
            f"  - closest approach without: {_closest(axis, points, 'rank swap, no avoidance')}.",
        ]
    return "\n".join(lines)
