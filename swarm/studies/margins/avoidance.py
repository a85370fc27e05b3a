"""The avoidance study's tables: closest approaches with and without eq.
11-13 on the paper's formation change, and the rank swap's sensitivity."""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from formation_swarm.studies.margins import PAPER_CHANGE, RANK_SWAP, avoidance_group
from formation_swarm.studies.margins.text import by_group, interval

Rows = Sequence[Mapping[str, Any]]


def _closest(runs: Sequence[Mapping[str, Any]]) -> str:
    """The closest approach of two robots' centres: min, 10th percentile, median, max over the seeds."""
    d = np.array([float(r["min_distance_m"]) for r in runs])
    p10, med = np.percentile(d, [10, 50])
    return f"{d.min():.2f} / {p10:.2f} / {med:.2f} / {d.max():.2f}"


def _rms(runs: Sequence[Mapping[str, Any]], rid: int) -> str:
    m, lo, hi = interval([float(r[f"r{rid}_rms_m"]) for r in runs])
    return f"{m:.2f} [{lo:.2f}, {hi:.2f}]"


def _rows(rows: Rows, cases: Sequence[tuple[str, str, Mapping[str, Any]]], diameter: Mapping[str, float]) -> list[str]:
    g = by_group(rows)
    out = []
    for label, _scenario, _ov in cases:
        for on in (True, False):
            runs = g[avoidance_group(label, on)]
            touch = sum(1 for r in runs if r["collisions"])
            posts = sum(1 for r in runs if r["obstacle_collisions"])
            out.append(
                f"| {label} | {'on' if on else 'off'} | {touch}/{len(runs)} | {posts}/{len(runs)} "
                f"| {_closest(runs)} | {diameter.get(label, 0.4):g} | {_rms(runs, 2)} | {_rms(runs, 3)} |"
            )
    return out


HEAD = [
    "| scenario | eq. 11-13 | seeds in which two robots touch | seeds in which a robot touches a post "
    "| closest approach of two centres, m: min / 10% / median / max | robot diameter, m "
    "| R2 formation error RMS, m | R3 formation error RMS, m |",
    "|---|---|---|---|---|---|---|---|",
]


def paper_change_table(rows: Rows) -> str:
    n = len(by_group(rows)[avoidance_group(PAPER_CHANGE[0][0], True)])
    lines = [
        f"The paper's triangle -> line -> triangle change, seeds 0-{n - 1}, with the partition-zone avoidance "
        "(eq. 11-13, as shipped) and without it (`controller.avoidance = false`: a follower goes straight to its "
        "new slot); formation errors as mean [95% interval] over the seeds; runs in one process "
        "(`formation_swarm.engine`).",
        "",
        *HEAD,
        *_rows(rows, PAPER_CHANGE, {}),
        "",
        *(f"- {_said(rows, label)}" for label, _s, _o in PAPER_CHANGE),
    ]
    return "\n".join(lines)


def _said(rows: Rows, label: str) -> str:
    g = by_group(rows)
    on, off = g[avoidance_group(label, True)], g[avoidance_group(label, False)]
    d_on = statistics.median(float(r["min_distance_m"]) for r in on)
    d_off = statistics.median(float(r["min_distance_m"]) for r in off)
    cost = statistics.fmean(float(a["r3_rms_m"]) - float(b["r3_rms_m"]) for a, b in zip(on, off, strict=True))
    closer = "closer" if d_on < d_off else "further apart"
    return (
        f"{label}: going straight, the closest approach's median is {d_off:.2f} m; with eq. 11-13 the robots come "
        f"{closer} ({d_on:.2f} m), and R3's formation error RMS changes by {cost:+.2f} m on average."
    )


def rank_swap_table(rows: Rows) -> str:
    n = len(by_group(rows)[avoidance_group(RANK_SWAP[0][0], True)])
    lines = [
        f"`fig11_rank_swap` one setting at a time, seeds 0-{n - 1}, with and without eq. 11-13; runs in one process "
        "(`formation_swarm.engine`). Slots moved: both rank formations' offsets moved along the reference's "
        "heading (`[1.3, -0.5]`, `[-1.3, -0.5]` back; `[1.3, 0.5]`, `[-1.3, 0.5]` ahead).",
        "",
        *HEAD,
        *_rows(rows, RANK_SWAP, {RANK_SWAP[4][0]: 0.3}),
    ]
    return "\n".join(lines)
