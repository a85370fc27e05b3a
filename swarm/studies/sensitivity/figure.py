"""The figure of one sensitivity axis (``swarm results --sensitivity``):
six panels against the axis's values, the five metrics of the claims (mean
and 95% interval per controller, the claim's threshold dashed) and the
share of seeds in which each claim holds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.common import palette
from formation_swarm.studies import claims
from formation_swarm.studies.sensitivity import LINES, METRICS, SHORT, Axis, Point

if TYPE_CHECKING:
    from matplotlib.figure import Figure

LOG_SCALE = ("r2_rms_m", "r2_max_m")
SYMLOG_SCALE = ("r2_turn_mean_lag_m", "r2_max_ahead_m")
# Each controller's colour, the same in every panel and every figure.
COLOURS = {name: i for i, name in enumerate((*LINES, "ekf"))}


def figure(axis: Axis, points: Sequence[Point]) -> Figure:
    """Six panels against the axis: the five metrics (mean and 95% interval per controller, the
    claim's threshold dashed) and the share of seeds in which each claim holds."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15, 8.2), layout="constrained")
    axes = fig.subplots(2, 3).ravel()
    for ax, metric in zip(axes, METRICS, strict=False):
        _metric_panel(ax, metric, points)
    _share_panel(axes[5], points)
    for ax in axes:
        ax.set_xlabel(f"{axis.title}, {axis.unit}")
        ax.set_xticks([p.value for p in points])
        ax.grid(alpha=0.3)
        for x, _what in axis.dotted:
            ax.axvline(x, color="0.6", ls=":", lw=1.0)
    for ax in (axes[0], axes[4], axes[5]):
        ax.legend(fontsize=8, loc="best")
    seeds = points[0].claims[0].seeds
    marks = [what if what != "the shipped value" else f"the shipped {axis.label(x)}" for x, what in axis.dotted]
    shipped = "; dotted: " + " and ".join(marks) if marks else ""
    fig.suptitle(
        f"The paper's claims against the {axis.title}\nmean and 95% interval over {seeds} seeds per "
        f"value{shipped}; dashed: the claim's threshold"
    )
    return fig


def _metric_panel(ax: Any, metric: tuple[str, str, tuple[str, ...], float | None], points: Sequence[Point]) -> None:
    """One metric's panel: per controller its mean and 95% interval at each value."""
    title, key, sweeps, thr = metric
    xs = [p.value for p in points]
    for name in sweeps:
        st = [p.stats.get((name, key)) for p in points]
        if all(s is None or s.n == 0 for s in st):
            continue
        mean = [s.mean if s else math.nan for s in st]
        half = [0.0 if s is None or math.isnan(s.half) else s.half for s in st]
        ax.errorbar(
            xs,
            mean,
            yerr=half,
            marker="o",
            ms=4,
            capsize=3,
            lw=1.4,
            color=palette.series_colour(COLOURS[name]),
            label=LINES.get(name, "fuzzy, dynamic V_N (claim c's run)"),
        )
    if thr is not None:
        ax.axhline(thr, color="0.3", ls="--", lw=1.0)
    if key in LOG_SCALE:
        _log_axis(ax)  # l-psi's 0.1 m and a static V_N's 10 m on one panel
        title += ", log scale"
    elif key in SYMLOG_SCALE and max((abs(m) for m in _means(points, key)), default=0.0) > 3.0:
        _symlog_axis(ax)  # the 0.25 and 0.5 m thresholds readable beside 10 m
        title += ", log > 1 m"
    ax.set_title(title, fontsize=10)


def _share_panel(ax: Any, points: Sequence[Point]) -> None:
    """The share of seeds in which each claim holds, at each value."""
    xs = [p.value for p in points]
    n = len(points[0].claims)
    step = (max(xs) - min(xs)) / max(1, len(xs) - 1) if len(xs) > 1 else 1.0
    for k in range(n):
        dodge = (k - (n - 1) / 2) * 0.05 * step  # side by side where several claims hold alike
        ax.plot(
            [x + dodge for x in xs],
            [100.0 * p.claims[k].holds / p.claims[k].seeds for p in points],
            marker="os^vD"[k % 5],
            ms=5,
            lw=1.2,
            label=f"claim {SHORT[claims.CLAIMS[k].__name__]}",
            color=palette.series_colour(k),
        )
    ax.set_ylim(-5, 105)
    ax.set_title("seeds in which the claim holds, %", fontsize=10)


def _means(points: Sequence[Point], key: str) -> list[float]:
    return [st.mean for p in points for (_name, k), st in p.stats.items() if k == key and st.n]


def _symlog_axis(ax: Any) -> None:
    """Linear within 1 m of 0, log beyond, labelled in plain numbers."""
    from matplotlib.ticker import FixedLocator, FuncFormatter

    ax.set_yscale("symlog", linthresh=1.0)
    ax.yaxis.set_major_locator(FixedLocator([-5, -2, -1, -0.5, 0, 0.25, 0.5, 1, 2, 5, 10, 20]))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))


def _log_axis(ax: Any) -> None:
    """A log y axis labelled in plain numbers: 0.1, 0.2, 0.5, 1, 2, 5, ..."""
    from matplotlib.ticker import FuncFormatter

    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))

    def minor(v: float, _pos: int) -> str:
        return f"{v:g}" if v > 0 and round(v / 10 ** math.floor(math.log10(v))) in (2, 5) else ""

    ax.yaxis.set_minor_formatter(FuncFormatter(minor))


def write_figure(path: Path, axis: Axis, points: Sequence[Point], dpi: int = 110) -> Path:
    fig = figure(axis, points)
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)
    fig.savefig(tmp, dpi=dpi)
    tmp.replace(path)  # never a half-written figure
    return path
