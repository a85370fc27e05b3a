"""Drawing shared by the figures: the time axis, the formation switches and
the fault lane under it, the note of a cut-off axis, and saving a figure."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from formation_swarm.report.figures.context import Context, Mark
from formation_swarm.report.figures.series import QUANTILE

LANE_FONT_PT = 7.5  # the fault lane's labels
LANE_ROW_IN = 0.2  # height of one row of the fault lane
CHAR_WIDTH = 0.6  # a label character's width, as a share of its font size (DejaVu Sans, about)


def time_axis(ax: Any, ctx: Context) -> None:
    ax.set_xlim(0.0, max(ctx.t_end, ctx.dt_s))
    ax.set_xlabel("time, s")
    ax.grid(alpha=0.3)


def time_marks(ax: Any, ctx: Context, beside: Sequence[Any] = ()) -> None:
    """Formation switches (dotted grey, labelled above the axes) and faults:
    shaded windows and dashed instants on the axes, and under them a lane
    with each fault's bar and label, in as many rows as keep the labels
    apart. The lane takes over the time axis's ticks and label."""
    lo, hi = ax.get_xlim()
    _switch_marks(ax, ctx.switches, lo, hi)
    marks = [(start, end, label) for start, end, label in ctx.fault_marks if start <= hi]
    if marks:
        _fault_lane(ax, marks, beside, (lo, hi))
    ax.set_xlim(lo, hi)


def _switch_marks(ax: Any, switches: Sequence[tuple[float, str]], lo: float, hi: float) -> None:
    for t, name in switches:  # labelled above the axes, out of the data's way
        ax.axvline(t, color="0.35", lw=1.0, ls=":", zorder=1)
        if lo <= t <= hi:
            ax.text(
                t,
                1.005,
                f"\u2192 {name}",
                transform=ax.get_xaxis_transform(),
                va="bottom",
                ha="center",
                fontsize=8,
                color="0.25",
            )


def _fault_lane(ax: Any, marks: Sequence[Mark], beside: Sequence[Any], span: tuple[float, float]) -> None:
    """Each fault shaded or dashed on ``ax`` (whose time axis spans ``span``),
    and its bar and label in a lane under it, which takes over the time axis."""
    lo, hi = span
    colors = [("tab:red", "darkred", "0.4")[k % 3] for k in range(len(marks))]  # none a robot's
    for color, (start, end, _) in zip(colors, marks, strict=True):
        if end is None:
            ax.axvline(start, color=color, lw=1.2, ls="--", zorder=1)
        else:
            ax.axvspan(start, min(end, hi), color=color, alpha=0.12, lw=0)
    fig = ax.figure
    axes_width_pt = fig.get_figwidth() * 72.0 * ax.get_position().width
    per_s = (hi - lo) / max(axes_width_pt, 1.0)  # seconds of the axis per point
    widths = [(len(label) + 1) * LANE_FONT_PT * CHAR_WIDTH * per_s for _, _, label in marks]
    rows = lane_rows([(a, min(b, hi) if b is not None else None) for a, b, _ in marks], widths)
    n_rows = max(rows) + 1
    # The lane takes the bottom of the axes' own cell of the figure's grid, so the
    # layout makes room for it and its labels (an inset's were cut off).
    axes_in = max(fig.get_figheight() * ax.get_position().height, 1.0)
    lane_in = LANE_ROW_IN * n_rows
    cells = ax.get_subplotspec().subgridspec(2, 1, height_ratios=[axes_in, lane_in], hspace=0.0)
    ax.set_subplotspec(cells[0])
    for other in beside:  # a panel sharing the y axis keeps the same height
        other.set_subplotspec(
            other.get_subplotspec().subgridspec(2, 1, height_ratios=[axes_in, lane_in], hspace=0.0)[0]
        )
    lane = fig.add_subplot(cells[1], sharex=ax)
    for color, row, width, (start, end, label) in zip(colors, rows, widths, marks, strict=True):
        if end is None:
            lane.plot([start, start], [row - 0.4, row + 0.4], color=color, lw=1.5, ls="--")
        else:
            lane.barh(row, min(end, hi) - start, left=start, height=0.8, color=color, alpha=0.3, lw=0)
        if start + width <= hi:
            lane.text(start, row, f" {label}", va="center", ha="left", fontsize=LANE_FONT_PT, color=color, clip_on=True)
        else:  # it would run off the axis's end: it ends there instead
            lane.text(hi, row, f"{label} ", va="center", ha="right", fontsize=LANE_FONT_PT, color=color, clip_on=True)
    lane.set_ylim(n_rows - 0.5, -0.5)
    lane.set_yticks([])
    lane.yaxis.set_label_position("right")  # on the left it met the axes' lowest tick label
    lane.set_ylabel("faults", rotation=0, ha="left", va="center", fontsize=8)
    lane.grid(axis="x", alpha=0.3)
    lane.set_xlabel(ax.get_xlabel())
    ax.set_xlabel("")
    ax.tick_params(axis="x", labelbottom=False)


def lane_rows(spans: Sequence[tuple[float, float | None]], label_widths: Sequence[float]) -> list[int]:
    """A row of the fault lane for each (start, end or None) span, whose label
    takes ``label_widths`` (same unit) from its start: the first row where it
    overlaps neither another span nor another label, in order of start."""
    ends: list[float] = []  # per row: where its last span or label ends
    out = [0] * len(spans)
    for k in sorted(range(len(spans)), key=lambda k: spans[k][0]):
        start, end = spans[k]
        reach = max(start + label_widths[k], end if end is not None else start)
        row = next((i for i, e in enumerate(ends) if e <= start), len(ends))
        if row == len(ends):
            ends.append(reach)
        else:
            ends[row] = reach
        out[k] = row
    return out


def cut_note(ax: Any, cut: float | None, unit: str = "m") -> None:
    if cut is not None:
        ax.text(
            0.995,
            0.99,
            f"axis cut at the {QUANTILE:g}th percentile; max {cut:.2f} {unit}",
            ha="right",
            va="top",
            transform=ax.transAxes,
            fontsize=7,
            color="0.3",
        )


def save(fig: Any, path: Any, dpi: int) -> None:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=dpi)
    plt.close(fig)
