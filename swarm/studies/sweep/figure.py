"""The figure of a sweep: each metric's mean over the seeds with its 95%
confidence interval (Student t, as in aggregate.csv) against the swept value,
one line per follower (the minimum distance between robots: one for the run).
``swarm sweep`` writes it next to runs.csv as aggregate.png.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.common.palette import robot_colour

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from formation_swarm.studies.jobs import Job

# Per-follower metrics (r<id>_<name> in runs.csv), then metrics of the whole run: name -> axis label.
PER_FOLLOWER = {
    "rms_m": "formation error RMS, m",
    "max_m": "largest formation error, m",
    "ekf_rms_m": "EKF target error RMS, m",
}
POOLED = {"min_distance_m": "least distance between robots, m"}


def swept(jobs: Sequence[Job]) -> dict[str, list[Any]]:
    """The override keys whose value differs between the jobs, each with its values in job order."""
    keys = sorted({k for j in jobs for k in j.overrides})
    out = {}
    for k in keys:
        values: list[Any] = []
        for j in jobs:
            v = j.overrides.get(k)
            if v not in values:
                values.append(v)
        if len(values) > 1:
            out[k] = values
    return out


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


@dataclass(frozen=True)
class _XAxis:
    """Where each combination sits along a panel's x axis, and how the axis reads."""

    labels: list[str]  # the combinations, in job order
    xs: dict[str, float]  # combination -> x
    title: str
    numeric: bool  # one numeric key swept: its values along the axis; else one tick per combination
    names: dict[str, str]  # combination -> its tick's text, when not numeric

    @property
    def step(self) -> float:
        """The mean distance between neighbouring combinations."""
        span = (max(self.xs.values()) - min(self.xs.values())) if len(self.xs) > 1 else 1.0
        return span / max(1, len(self.xs) - 1)


def _x_axis(jobs: Sequence[Job]) -> _XAxis:
    labels = list(dict.fromkeys(j.label for j in jobs))
    keys = swept(jobs)
    if len(keys) == 1 and all(_is_number(v) for v in next(iter(keys.values()))):
        key = next(iter(keys))
        first = {}
        for j in jobs:
            first.setdefault(j.label, j.overrides[key])
        return _XAxis(labels=labels, xs={lab: float(first[lab]) for lab in labels}, title=key, numeric=True, names={})
    # One tick per combination, named by its value when one key is swept.
    names = {j.label: str(j.overrides[next(iter(keys))]) if len(keys) == 1 else j.label or "base" for j in jobs}
    return _XAxis(
        labels=labels,
        xs={lab: float(k) for k, lab in enumerate(labels)},
        title=" x ".join(keys) or "combination",
        numeric=False,
        names=names,
    )


def _panels(metrics: set[str]) -> list[tuple[str, list[tuple[str, str]]]]:
    """The panels of the metrics present: (axis label, [(metric, line label)])."""
    panels: list[tuple[str, list[tuple[str, str]]]] = []
    for name, ylabel in PER_FOLLOWER.items():
        lines = sorted(
            (
                (m, f"R{m[1 : -len(name) - 1]}")
                for m in metrics
                if m.startswith("r") and m[1 : -len(name) - 1].isdigit() and m.endswith("_" + name)
            ),
            key=lambda ml: int(ml[1][1:]),
        )
        if lines:
            panels.append((ylabel, lines))
    return panels + [(ylabel, [(name, "all robots")]) for name, ylabel in POOLED.items() if name in metrics]


def figure(agg: Sequence[Mapping[str, Any]], jobs: Sequence[Job], title: str = "") -> Figure:
    """One panel per metric present in ``agg`` (aggregate()'s rows); in each, one
    error bar line per follower (or one for a pooled metric) over the combinations."""
    from matplotlib.figure import Figure

    x = _x_axis(jobs)
    by = {(r["combination"], r["metric"]): r for r in agg}
    metrics = {r["metric"] for r in agg}
    panels = _panels(metrics)
    n = max(1, len(panels))
    cols = 2 if n > 1 else 1
    rows = (n + cols - 1) // cols
    fig = Figure(figsize=(6 * cols, 3.6 * rows + 0.6), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax, (ylabel, lines) in zip(axes, panels, strict=False):
        _draw_panel(ax, ylabel, lines, x, by)
    for ax in axes[len(panels) :]:
        ax.axis("off")
    if "ekf_rms_m" not in {name for name in PER_FOLLOWER if any(m.endswith("_" + name) for m in metrics)}:
        spare = axes[len(panels)] if len(panels) < len(axes) else None
        note = "no EKF target errors: they come from the recordings (swarm sweep --logger)"
        if spare is not None:
            spare.text(0.5, 0.5, note, ha="center", va="center", fontsize=9, color="0.35", transform=spare.transAxes)
    seeds = sorted({j.seed for j in jobs})
    head = f"{title}: " if title else ""
    per = f"{len(seeds)} seed{'s' if len(seeds) != 1 else ''} per value"
    fig.suptitle(
        f"{head}mean and 95% confidence interval over {per}"
        if len(seeds) > 1
        else f"{head}{per}, no confidence interval"
    )
    return fig


MANY_LINES = 8  # beyond this many followers a panel draws each faint, with their median and the worst


def _draw_panel(
    ax: Any, ylabel: str, lines: list[tuple[str, str]], x: _XAxis, by: Mapping[tuple[str, str], Mapping[str, Any]]
) -> None:
    """One panel: each line's mean and confidence interval at each combination."""
    many = len(lines) > MANY_LINES
    ls = "-" if x.numeric else "none"
    for k, (metric, line_label) in enumerate(lines):
        dodge = 0.0 if many else (k - (len(lines) - 1) / 2) * 0.06 * x.step  # several robots' bars side by side
        pts = [(x.xs[lab] + dodge, by[lab, metric]) for lab in x.labels if (lab, metric) in by]
        xs = [p[0] for p in pts]
        mean = [p[1]["mean"] for p in pts]
        low = [p[1]["mean"] - p[1]["ci95_low"] if p[1]["n"] > 1 else 0.0 for p in pts]
        high = [p[1]["ci95_high"] - p[1]["mean"] if p[1]["n"] > 1 else 0.0 for p in pts]
        colour = robot_colour(int(line_label[1:])) if line_label[1:].isdigit() else "0.3"
        if many:  # each faint, unlabelled: their median and the worst are drawn over them
            ax.plot(xs, mean, marker="o", ms=2, lw=0.7, color=colour, alpha=0.35, ls=ls)
        else:
            ax.errorbar(
                xs, mean, yerr=[low, high], marker="o", ms=4, capsize=4, lw=1.2, label=line_label, color=colour, ls=ls
            )
    if many:
        _median_and_worst(ax, lines, x, by)
    ax.set_ylabel(ylabel)
    ax.set_xlabel(x.title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    if x.numeric and len(x.labels) <= 12:
        ax.set_xticks(sorted(set(x.xs.values())))
    if not x.numeric:
        ax.set_xticks(
            [x.xs[lab] for lab in x.labels],
            [x.names[lab] for lab in x.labels],
            rotation=20 if sum(len(x.names[lab]) for lab in x.labels) > 60 else 0,
            fontsize=8,
        )


def _median_and_worst(
    ax: Any, lines: list[tuple[str, str]], x: _XAxis, by: Mapping[tuple[str, str], Mapping[str, Any]]
) -> None:
    """Over a panel's faint follower lines: the median of their means at each
    value, and the follower whose mean is largest, named."""
    import statistics

    ls = "-" if x.numeric else "none"
    labels, xs = x.labels, x.xs
    xs_drawn, medians = [], []
    for lab in labels:
        means = [by[lab, metric]["mean"] for metric, _ in lines if (lab, metric) in by]
        if means:
            xs_drawn.append(xs[lab])
            medians.append(statistics.median(means))
    ax.plot(
        xs_drawn, medians, marker="o", ms=4, lw=2.0, color="k", ls=ls, label=f"median over the {len(lines)} followers"
    )
    worst_metric, worst_label = max(
        lines, key=lambda ml: max((by[lab, ml[0]]["mean"] for lab in labels if (lab, ml[0]) in by), default=-1.0)
    )
    pts = [(xs[lab], by[lab, worst_metric]["mean"]) for lab in labels if (lab, worst_metric) in by]
    ax.plot(
        [p[0] for p in pts],
        [p[1] for p in pts],
        marker="o",
        ms=4,
        lw=1.5,
        ls=ls,
        color=robot_colour(int(worst_label[1:])),
        label=f"largest mean at any value: {worst_label}",
    )


def write(path: Path, agg: Sequence[Mapping[str, Any]], jobs: Sequence[Job], title: str = "") -> Path:
    """The figure of ``agg`` into ``path``; its path."""
    fig = figure(agg, jobs, title)
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)
    fig.savefig(tmp, dpi=110)
    tmp.replace(path)  # never a half-written figure
    return path
