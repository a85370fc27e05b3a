"""The figures of one value per follower over time: the formation error
(Fig. 6b/d, 7b) and V_N (Fig. 8), each follower in its colour, or for a
swarm each faint under their median, the worst named."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from formation_swarm.common.palette import robot_colour
from formation_swarm.report.figures import drawing
from formation_swarm.report.figures.context import Context
from formation_swarm.report.figures.series import Series, gapped, median_over, moving_average, robust_top

VN_SMOOTH_S = 1.0  # the moving average drawn over V_N, display only


def formation_error(path: Any, data: Mapping[str, Series], ctx: Context, rms: Mapping[int, Any], dpi: int) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4), layout="constrained")
    arrays = []
    drawn: dict[int, Series] = {}
    for r in ctx.followers:
        s = data.get(f"/robots/r{r}/error/formation")
        if s is None or not len(s):
            continue
        value = rms.get(r)
        whole = ", whole run" if ctx.cut else ""  # the lines end at the cut; the world's RMS does not
        tag = f" (RMS {value:.2f} m{whole})" if isinstance(value, (int, float)) else " (never acquired its reference)"
        if ctx.many:
            ax.plot(*gapped(s.t, s.v, ctx.dt_s), lw=0.7, color=ctx.colour(r), alpha=0.35)
        else:
            ax.plot(*gapped(s.t, s.v, ctx.dt_s), lw=1.5, color=ctx.colour(r), label=f"R{r}{tag}")
        arrays.append(s.v)
        drawn[r] = s
    if ctx.many and drawn:
        _swarm_lines(ax, drawn, rms, ctx.dt_s, what="RMS", unit="m")
    top, cut = robust_top(arrays)
    ax.set_ylim(0.0, top)
    drawing.time_axis(ax, ctx)
    ax.set_ylabel("distance to its true target, m")
    # Over the whole figure: over the axes alone a long one (a cut recording's) ran past the left edge.
    fig.suptitle(ctx.title("formation_error", "each follower's formation error"), fontsize=11)
    if arrays:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    drawing.time_marks(ax, ctx)
    drawing.cut_note(ax, cut)
    drawing.save(fig, path, dpi)


def _swarm_lines(
    ax: Any, drawn: Mapping[int, Series], score: Mapping[int, Any], dt_s: float, *, what: str, unit: str
) -> None:
    """Over the followers drawn faint: their median (bold black) and the one
    of largest ``score`` (its own colour), each in the legend."""
    grid, median = median_over({r: (s.t, s.v) for r, s in drawn.items()})
    ax.plot([], [], lw=0.7, color="0.5", alpha=0.6, label=f"each of the {len(drawn)} followers, faint")
    ax.plot(*gapped(grid, median, dt_s), lw=2.0, color="k", label=f"median over the {len(drawn)} followers")
    scored = [
        (float(v), r) for r, v in score.items() if r in drawn and isinstance(v, (int, float)) and math.isfinite(v)
    ]
    if scored:
        value, worst = max(scored)
        s = drawn[worst]
        ax.plot(
            *gapped(s.t, s.v, dt_s),
            lw=1.6,
            color=robot_colour(worst),
            label=f"largest {what}: R{worst} ({value:.2f} {unit})",
        )


def vn(path: Any, data: Mapping[str, Series], ctx: Context, dpi: int) -> None:
    import matplotlib.pyplot as plt

    fig, (ax, hist) = plt.subplots(
        1, 2, figsize=(10, 4.2), sharey=True, layout="constrained", gridspec_kw={"width_ratios": [4, 1]}
    )
    drawn, averages, held = _vn_lines(ax, data, ctx)
    if not drawn:
        ax.text(0.5, 0.5, _no_vn(ctx), ha="center", transform=ax.transAxes)
        hist.axis("off")
    else:
        lo = min(float(np.min(v)) for _, v in drawn)
        hi = max(float(np.max(v)) for _, v in drawn)
        pad = max(0.05, 0.08 * (hi - lo))
        ax.set_ylim(lo - pad, hi + pad)
        edges = np.linspace(lo - 1e-9, hi + 1e-9, 11) if hi - lo > 1e-6 else np.array([lo - 0.025, lo + 0.025])
        if ctx.many:
            _pooled_shares(ax, hist, drawn, averages, edges=edges, dt_s=ctx.dt_s)
        else:
            _each_shares(hist, drawn, edges, ctx)
            ax.plot([], [], lw=0.5, color="0.4", alpha=0.5, label="V_N each tick, as the controller used it")
        hist.set_xlabel("share of ticks, %")
        hist.set_title("time at each V_N", fontsize=9)
        hist.grid(alpha=0.3)
        # Under the figure: inside, it would hide the V_N lines it names.
        ax.figure.legend(*ax.get_legend_handles_labels(), fontsize=8, loc="outside lower center", ncol=3, frameon=False)
    drawing.time_axis(ax, ctx)
    ax.set_ylabel("V_N, m/s")
    note = f"\n{held} ticks holding (V_N = 0) not drawn" if held else ""
    faint = f"each follower's {VN_SMOOTH_S:g} s" if ctx.many else f"every tick; bold: {VN_SMOOTH_S:g} s"
    # Over the whole figure: over the V_N axes alone its lines ran past the figure's left edge.
    ax.figure.suptitle(
        ctx.title("vn", "FIS-2's normal speed V_N") + f"\nfaint: {faint} "
        f"centred moving average, for the eye only (the controller is not filtered){note}",
        fontsize=10,
    )
    drawing.time_marks(ax, ctx, beside=[hist])
    drawing.save(fig, path, dpi)


def _no_vn(ctx: Context) -> str:
    """Why the V_N figure has no line: the followers' laws sent none."""
    flown = ctx.laws_of_followers()
    if not flown:
        return "no V_N in this run: its followers sent none"
    return f"no V_N in this run: law{'s' if len(flown) > 1 else ''} {', '.join(flown)} sent none"


def _vn_lines(
    ax: Any, data: Mapping[str, Series], ctx: Context
) -> tuple[list[tuple[int, np.ndarray]], dict[int, tuple[np.ndarray, np.ndarray]], int]:
    """Each follower's V_N while it flies, and its moving average: the V_N
    drawn per follower, the averages (kept for a swarm's median) and the
    ticks spent holding, which are not drawn."""
    drawn: list[tuple[int, np.ndarray]] = []
    averages: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    held = 0
    for r in ctx.followers:
        s = data.get(f"/robots/r{r}/fis/v_n")
        if s is None or not len(s):
            continue
        flying = s.v > 0.0  # 0: holding at a standing reference (docs/paper.md), not FIS-2's output
        held += int(np.sum(~flying))
        t, v = s.t[flying], s.v[flying]
        if not len(v):
            continue
        c = ctx.colour(r)
        smooth = moving_average(t, v, VN_SMOOTH_S, ctx.dt_s)
        if ctx.many:  # each follower's average faint; their median over it
            ax.plot(*gapped(t, smooth, ctx.dt_s), lw=0.7, color=c, alpha=0.35)
            averages[r] = (t, smooth)
        else:
            ax.plot(*gapped(t, v, ctx.dt_s), lw=0.5, color=c, alpha=0.3)
            ax.plot(
                *gapped(t, smooth, ctx.dt_s),
                lw=1.8,
                color=c,
                label=f"R{r}: {VN_SMOOTH_S:g} s moving average (mean {np.mean(v):.2f} m/s)",
            )
        drawn.append((r, v))
    return drawn, averages, held


def _pooled_shares(
    ax: Any,
    hist: Any,
    drawn: list[tuple[int, np.ndarray]],
    averages: Mapping[int, tuple[np.ndarray, np.ndarray]],
    *,
    edges: np.ndarray,
    dt_s: float,
) -> None:
    """A swarm: every follower's ticks in one set of bars, and the median of their averages."""
    pooled = np.concatenate([v for _, v in drawn])
    share, _ = np.histogram(pooled, bins=edges)
    hist.barh(
        edges[:-1] + 0.5 * np.diff(edges),
        100.0 * share / len(pooled),
        height=0.9 * np.diff(edges),
        color="0.45",
        label=f"all {len(drawn)} followers",
    )
    grid, median = median_over(averages)
    ax.plot(
        [],
        [],
        lw=0.7,
        color="0.5",
        alpha=0.6,
        label=f"each follower's {VN_SMOOTH_S:g} s moving average ({len(drawn)}), faint",
    )
    ax.plot(
        *gapped(grid, median, dt_s),
        lw=2.0,
        color="k",
        label=f"median over the {len(drawn)} followers' averages",
    )


def _each_shares(hist: Any, drawn: list[tuple[int, np.ndarray]], edges: np.ndarray, ctx: Context) -> None:
    """The followers' bars side by side in each band of V_N."""
    width = 0.9 * np.diff(edges) / len(drawn)
    for k, (r, v) in enumerate(drawn):
        share, _ = np.histogram(v, bins=edges)
        hist.barh(
            edges[:-1] + (k + 0.55) * width,
            100.0 * share / len(v),
            height=width,
            color=ctx.colour(r),
            label=f"R{r}",
        )
