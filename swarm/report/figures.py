"""The four figures of ``swarm report``, drawn with matplotlib from a run's
recording (``data.read_recording``) and summary.

Choices a reader should know, also said on the figures themselves:

- Trajectories: formation snapshots at the formation events (a formation
  code changes) and in the middle of each stretch flown in one formation,
  each also drawn alone, zoomed, like the paper's Fig. 11 (a-d). A run with
  no formation change gets evenly timed snapshots on one panel.
- V_N: FIS-2's output changes every tick (it is what the controller used,
  unfiltered); drawn faint, with a 1 s centred moving average over it (for
  the eye only), and beside it the share of ticks at each V_N.
- Every time axis marks the formation switches (dotted, "-> line") and the
  faults (dashed instants, shaded windows). Limits are robust: a y axis goes
  to the 99.5th percentile with a margin, and says where a larger value was
  cut off.
- Titles name the scenario and the seed, and "cf. Fig. N" only when the run
  is a shipped scenario of the paper as shipped (any seed).
- A line is not drawn across a gap in its series (an agent killed, frozen
  or restarted; a follower holding, which has no V_N), nor is a moving
  average taken across one.
- Beyond LEGEND_FOLLOWERS followers (a swarm), no figure lists every robot:
  the formation error and V_N draw each follower faint under their median
  and name the worst, the trajectories name the leader and the followers as
  one entry, and the targets figure shows the followers of largest error.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from formation_swarm.common.palette import robot_colour

Series = Any  # data.Series: .t (s) and .v, time-sorted
Mark = tuple[float, "float | None", str]

VN_SMOOTH_S = 1.0  # the moving average drawn over V_N, display only
EVENT_GAP_S = 1.0  # formation events closer than this are one switch (leader, then its followers)
LETTERS = "abcdefghijklmnopqrstuvwxyz"  # panel letters, as the paper's Fig. 11 (a-d)
MAX_PANELS = 9  # zoomed snapshots on the trajectory figure
MIN_HELD_S = 2.0  # a formation flown shorter than this gets no mid-way snapshot
NARROW_VIEW_IN = 3.5  # a trajectory view narrower than this gets its legend beside it, not over it
LEGEND_WIDTH_IN = 3.0  # what a swarm's trajectory figure without zoomed panels grows by, for its legend beside it
QUANTILE = 99.5  # robust axis limits: this percentile, with a margin
# Beyond this many followers a figure draws them together (each faint, their
# median bold, the worst named) rather than one legend entry each, and names
# only some robots on the zoomed snapshots; the targets figure shows the
# TARGET_ROWS followers of largest formation error.
LEGEND_FOLLOWERS = 8
TARGET_ROWS = 4
NAMED_EVERY = 5  # on a zoomed snapshot of many robots: the leader and every 5th robot are named
GAP_TICKS = 1.5  # a series with no row for longer than this many ticks has a gap: no line across it


@dataclass
class Context:
    """What every figure of one run needs besides the recording."""

    scenario: str
    seed: Any
    robots: list[int]
    followers: list[int]
    dt_s: float = 0.05
    t_end: float = 0.0
    paper: Mapping[str, str] = field(default_factory=dict)  # figure stem -> "Fig. 7a", when reproduced
    changes: str | None = None  # else, for a paper's scenario that was changed, what was (report.paper_changes)
    fault_marks: list[Mark] = field(default_factory=list)
    cut: str = ""  # the recording ends early (its logger killed): said in every title
    switches: list[tuple[float, str]] = field(default_factory=list)  # (time s, formation)
    formation_events: list[Mapping[str, Any]] = field(default_factory=list)
    formations: Mapping[str, Mapping[int, tuple[int, tuple[float, float]]]] = field(default_factory=dict)
    start_formation: str | None = None
    obstacles: list[tuple[float, float, float]] = field(default_factory=list)
    diameter_m: float = 0.4

    def title(self, stem: str, what: str) -> str:
        cf = f" (cf. paper {self.paper[stem]})" if stem in self.paper else ""
        cut = f" [{self.cut}]" if self.cut else ""
        return f"{self.scenario}, seed {self.seed}: {what}{cf}{cut}"

    @property
    def many(self) -> bool:
        """A swarm: too many followers for one legend entry each."""
        return len(self.followers) > LEGEND_FOLLOWERS

    def colour(self, rid: int) -> tuple[float, float, float]:
        """The robot's colour, the same as in the Rerun viewer (formation_swarm.common.palette)."""
        return robot_colour(rid)

    def flown(self, rid: int, t: float) -> str | None:
        """The formation robot ``rid`` flies at time ``t``."""
        name = self.start_formation
        for e in self.formation_events:
            if e.get("robot") == rid and isinstance(e.get("time_s"), (int, float)) and e["time_s"] <= t + 1e-9:
                name = str(e.get("formation"))
        return name


def switches(events: Sequence[Mapping[str, Any]]) -> list[tuple[float, str]]:
    """Formation switches of a run: its formation events grouped (a leader's
    change and its followers' within EVENT_GAP_S), each at its first event."""
    out: list[tuple[float, str]] = []
    last = -math.inf
    for e in sorted((e for e in events if isinstance(e.get("time_s"), (int, float))), key=lambda e: e["time_s"]):
        t = float(e["time_s"])
        if t - last > EVENT_GAP_S:
            out.append((t, str(e.get("formation"))))
        last = t
    return out


def snapshot_times(switch_times: Sequence[float], t_end: float, evenly: int) -> list[tuple[float, str]]:
    """When to draw the formation: with switches, the start, each switch and the
    middle of the stretch after it; without, ``evenly`` times from start to end.
    Each with its kind: "start", "switch", "held" or "even"."""
    if not switch_times:
        return [(float(t), "even") for t in np.linspace(0.0, t_end, evenly)] if evenly else []
    out = [(0.0, "start")]
    bounds = [*switch_times, t_end]
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        out.append((a, "switch"))
        if b - a >= MIN_HELD_S:  # a shorter stretch's middle looks like its switch
            out.append((0.5 * (a + b), "held"))
    return out


def robust_top(arrays: Sequence[np.ndarray], floor: float = 0.0) -> tuple[float, float | None]:
    """An upper y limit that a few outliers do not blow out: the 99.5th
    percentile of all the values plus 15%, or their maximum plus 5% when that
    is not much larger. Also the maximum when it is cut off, else None."""
    vals = np.concatenate([np.asarray(a, dtype=float).ravel() for a in arrays]) if arrays else np.zeros(0)
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return max(floor, 1.0), None
    top, q = float(np.max(vals)), float(np.percentile(vals, QUANTILE))
    if top <= 1.5 * q or q <= 0.0:
        return max(floor, 1.05 * top if top > 0 else 1.0), None
    return max(floor, 1.15 * q), top


def stretches(t: np.ndarray, dt_s: float) -> list[slice]:
    """The unbroken stretches of a time series: a gap of more than GAP_TICKS
    ticks (an agent killed, frozen or restarted; a robot out of its camera's
    view) ends one."""
    breaks = np.flatnonzero(np.diff(t) > GAP_TICKS * dt_s) + 1
    edges = [0, *breaks.tolist(), len(t)]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def gapped(t: np.ndarray, v: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``t`` and ``v`` with a NaN between stretches, so that a line is not drawn across a gap."""
    parts = stretches(t, dt_s)
    if len(parts) <= 1:
        return t, v
    gap = np.full((1, *np.shape(v)[1:]), np.nan)
    ts, vs = [], []
    for k, sl in enumerate(parts):
        if k:
            ts.append(np.array([0.5 * (t[sl.start - 1] + t[sl.start])]))
            vs.append(gap)
        ts.append(t[sl])
        vs.append(v[sl])
    return np.concatenate(ts), np.concatenate(vs)


def moving_average(t: np.ndarray, v: np.ndarray, window_s: float, dt_s: float) -> np.ndarray:
    """Centred moving average over ``window_s`` (in ticks of ``dt_s``); shorter at
    the ends of each unbroken stretch, none of which averages across a gap."""
    n = max(1, int(round(window_s / dt_s)))
    if n <= 1 or len(v) < 2:
        return v.copy()
    out = np.empty(len(v))
    kernel = np.ones(n)
    for sl in stretches(t, dt_s):
        part = v[sl]
        out[sl] = np.convolve(part, kernel, mode="same") / np.convolve(np.ones_like(part), kernel, mode="same")
    return out


def _time_marks(ax: Any, ctx: Context, beside: Sequence[Any] = ()) -> None:
    """Formation switches (dotted grey, labelled above the axes) and faults:
    shaded windows and dashed instants on the axes, and under them a lane
    with each fault's bar and label, in as many rows as keep the labels
    apart. The lane takes over the time axis's ticks and label."""
    lo, hi = ax.get_xlim()
    for t, name in ctx.switches:  # labelled above the axes, out of the data's way
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
    marks = [(start, end, label) for start, end, label in ctx.fault_marks if start <= hi]
    if not marks:
        ax.set_xlim(lo, hi)
        return
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
    ax.set_xlim(lo, hi)


LANE_FONT_PT = 7.5  # the fault lane's labels
LANE_ROW_IN = 0.2  # height of one row of the fault lane
CHAR_WIDTH = 0.6  # a label character's width, as a share of its font size (DejaVu Sans, about)


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


def _cut_note(ax: Any, cut: float | None, unit: str = "m") -> None:
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


def _time_axis(ax: Any, ctx: Context) -> None:
    ax.set_xlim(0.0, max(ctx.t_end, ctx.dt_s))
    ax.set_xlabel("time, s")
    ax.grid(alpha=0.3)


def _save(fig: Any, path: Any, dpi: int) -> None:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=dpi)
    plt.close(fig)


# -- trajectories (Fig. 6a/c, 7a, 11) ----------------------------------------------------------------


def trajectories(path: Any, data: Mapping[str, Series], ctx: Context, snapshots: int, dpi: int) -> None:
    import matplotlib.pyplot as plt

    poses = {r: data[f"/robots/r{r}/pose"] for r in ctx.robots if len(data[f"/robots/r{r}/pose"])}
    snaps = snapshot_times([t for t, _ in ctx.switches], ctx.t_end, snapshots)
    snaps = snaps if not ctx.switches else snaps[:MAX_PANELS]  # the first switches, when there are many
    evenly = len(snaps)
    if not ctx.switches:  # a long formation covers the next snapshot's: fewer, apart
        snaps = apart([(t, kind, _at(poses, t)) for t, kind in snaps])
    zoomed = [s for s in snaps if s[1] != "even"]
    lo, hi = _extent(poses, ctx.obstacles)
    if zoomed:
        cols = math.ceil(len(zoomed) / 2)
        fig = plt.figure(figsize=(4.2 + 3.6 * cols, 8.6), layout="constrained")
        grid = fig.add_gridspec(2, 1 + cols, width_ratios=[1.2] + [1.0] * cols)
        over = fig.add_subplot(grid[:, 0])
        panels = [fig.add_subplot(grid[i // cols, 1 + i % cols]) for i in range(len(zoomed))]
        spare = [grid[i // cols, 1 + i % cols] for i in range(len(zoomed), 2 * cols)]
        beside = False  # the legend has a panel of its own, or the overview's room
    else:
        # As wide as the view's equal scales need (a column is narrow), no wider; a
        # swarm's legend, or one a narrow view could not hold, goes beside it.
        _, span = equal_view(lo, hi)
        height = float(np.clip(6.0 * span[1] / span[0], 4.5, 7.5))
        axes_width = (height - 1.4) * span[0] / span[1]
        beside = ctx.many or axes_width < NARROW_VIEW_IN
        width = float(np.clip(axes_width + 1.3 + LEGEND_WIDTH_IN * beside, 5.5, 12.0 + LEGEND_WIDTH_IN))
        fig, over = plt.subplots(figsize=(width, height), layout="constrained")
        panels, spare = [], []
    _overview(over, poses, ctx, snaps, lo, hi)
    for k, (ax, (t, kind)) in enumerate(zip(panels, zoomed, strict=True)):
        _zoom(ax, data, poses, ctx, t, kind, LETTERS[k])
    handles, labels = over.get_legend_handles_labels()
    if spare:
        leg_ax = fig.add_subplot(spare[0])
        leg_ax.axis("off")
        leg_ax.legend(handles, labels, loc="center", fontsize=9, frameon=False)
    elif not zoomed and beside:  # beside the axes, in a figure made wider for it
        over.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)
        over.set_anchor("E")  # the axes beside their legend; any spare width goes to the left
    else:
        over.legend(handles, labels, loc="best", fontsize=8)
    if zoomed:
        last = LETTERS[len(zoomed) - 1]
        how = f"snapshots (black) at each formation switch and mid-way through each formation, zoomed in (a)-({last})"
    else:
        how = f"formation every {ctx.t_end / max(1, snapshots - 1):.1f} s (no formation switch)"
        if len(snaps) < evenly:
            times = ", ".join(f"{t:.1f}" for t, _ in snaps)
            how = f"formation at {times} s (no formation switch; overlapping ones left out)"
    fig.suptitle(ctx.title("trajectories", "trajectories") + f"\n{how}", fontsize=11)
    _save(fig, path, dpi)


SNAPSHOT_GAP_M = 1.0  # kept snapshots' boxes are at least this far apart


def apart(snaps: Sequence[tuple[float, str, Mapping[int, np.ndarray]]]) -> list[tuple[float, str]]:
    """The snapshots (time, kind, positions) whose robots' bounding boxes,
    grown by SNAPSHOT_GAP_M / 2, meet none of those kept before them (the
    first is always kept). A column of 30
    robots is 40 m long; drawn every 10 s on a path it flies at 1.5 m/s, its
    snapshots lay over one another."""
    kept: list[tuple[float, str]] = []
    boxes: list[tuple[np.ndarray, np.ndarray]] = []
    for t, kind, pts in snaps:
        if not pts:
            continue
        xy = np.array(list(pts.values()))[:, :2]
        lo, hi = xy.min(axis=0) - SNAPSHOT_GAP_M / 2, xy.max(axis=0) + SNAPSHOT_GAP_M / 2
        if all(np.any(hi < blo) or np.any(lo > bhi) for blo, bhi in boxes):
            kept.append((t, kind))
            boxes.append((lo, hi))
    return kept


def _extent(poses: Mapping[int, Series], obstacles: list[tuple[float, float, float]]) -> tuple[np.ndarray, np.ndarray]:
    pts = [s.v for s in poses.values()] + [np.array([[x - r, y - r], [x + r, y + r]]) for x, y, r in obstacles]
    allp = np.concatenate(pts) if pts else np.zeros((1, 2))
    return np.min(allp, axis=0), np.max(allp, axis=0)


def _overview(
    ax: Any, poses: Mapping[int, Series], ctx: Context, snaps: list[tuple[float, str]], lo: np.ndarray, hi: np.ndarray
) -> None:
    import matplotlib.pyplot as plt

    for x, y, r in ctx.obstacles:
        ax.add_patch(plt.Circle((x, y), r, color="tab:red", alpha=0.35, lw=0))
    if ctx.obstacles:
        ax.plot([], [], "o", color="tab:red", alpha=0.35, label="obstacle")
    for r, s in poses.items():
        leader = r not in ctx.followers
        label = f"R{r}" + (" (leader)" if leader else "") if leader or not ctx.many else None
        ax.plot(s.v[:, 0], s.v[:, 1], lw=1.8, color=ctx.colour(r), label=label)
    if ctx.many:  # one entry for them all: each still in its own colour, as in the Rerun viewer
        ax.plot([], [], lw=1.8, color="0.55", label=f"{len(ctx.followers)} followers, each in its own colour")
    letters = iter(LETTERS)
    for k, (t, kind) in enumerate(snaps):
        pts = _at(poses, t)
        _links(ax, ctx, pts, t, lw=0.9, label="formation (follower to its reference)" if k == 0 else None)
        ax.scatter(*np.array(list(pts.values())).T, s=12, color="k", zorder=4)
        c = np.mean(np.array(list(pts.values())), axis=0)
        if ctx.many and (head := [p for r, p in pts.items() if r not in ctx.followers]):
            c = head[0]  # a long formation's label at its leader, its head
        ax.annotate(
            f"({next(letters)})" if kind != "even" else f"{t:.1f} s",
            c,
            xytext=(14, 0),
            textcoords="offset points",
            fontsize=9,
            va="center",
            bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "none", "pad": 0.5},
        )
    centre, span = equal_view(lo, hi)
    ax.set_xlim(centre[0] - span[0] / 2, centre[0] + span[0] / 2)
    ax.set_ylim(centre[1] - span[1] / 2, centre[1] + span[1] / 2)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x, m")
    ax.set_ylabel("y, m")
    ax.grid(alpha=0.3)


def equal_view(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The overview's centre and (x, y) span, m, for data from ``lo`` to ``hi``:
    equal scales, and a long thin path gets a wider view rather than a squashed one."""
    span = np.maximum(hi - lo, 1.0) + 3.0
    return 0.5 * (lo + hi), np.maximum(span, span.max() / 3.0)


def _at(poses: Mapping[int, Series], t: float) -> dict[int, np.ndarray]:
    return {r: s.v[min(int(np.searchsorted(s.t, t - 1e-9)), len(s) - 1)] for r, s in poses.items()}


def _links(ax: Any, ctx: Context, pts: Mapping[int, np.ndarray], t: float, lw: float, label: str | None) -> None:
    """Each follower joined to its reference in the formation it flies at ``t``."""
    for r in ctx.followers:
        slot = ctx.formations.get(ctx.flown(r, t) or "", {}).get(r)
        if slot is None or r not in pts or slot[0] not in pts:
            continue
        (x0, y0), (x1, y1) = pts[slot[0]], pts[r]
        ax.plot([x0, x1], [y0, y1], color="0.25", lw=lw, ls="--", zorder=3, label=label)
        label = None


def _zoom(
    ax: Any, data: Mapping[str, Series], poses: Mapping[int, Series], ctx: Context, t: float, kind: str, letter: str
) -> None:
    import matplotlib.pyplot as plt

    pts = _at(poses, t)
    centre = np.mean(np.array(list(pts.values())), axis=0)
    half = max(4.0, 0.5 * float(np.ptp(np.array(list(pts.values())), axis=0).max()) + 2.0)
    for x, y, r in ctx.obstacles:
        ax.add_patch(plt.Circle((x, y), r, color="tab:red", alpha=0.35, lw=0))
    for r, s in poses.items():
        near = (s.t >= t - 4.0) & (s.t <= t + 4.0)  # 4 s either side: where it came from, where it goes
        ax.plot(s.v[near, 0], s.v[near, 1], lw=1.0, color=ctx.colour(r), alpha=0.8)
        ax.add_patch(plt.Circle(tuple(pts[r]), 0.5 * ctx.diameter_m, color=ctx.colour(r), zorder=4))
        if not ctx.many or r not in ctx.followers or r % NAMED_EVERY == 0:
            ax.annotate(f"R{r}", tuple(pts[r]), xytext=(6, 6), textcoords="offset points", fontsize=8, zorder=5)
    _links(ax, ctx, pts, t, lw=1.0, label=None)
    for r in ctx.followers:
        tgt = data.get(f"/robots/r{r}/target/true")
        if tgt is not None and len(tgt):
            ax.plot(*_at({r: tgt}, t)[r], marker="x", color=ctx.colour(r), ms=7, mew=1.5, zorder=5)
    leader = next((r for r in ctx.robots if r not in ctx.followers), None)
    name = ctx.flown(leader, t) if leader is not None else None
    what = {"start": f"start, {name}", "switch": f"switch to {name}", "held": f"{name}"}.get(kind, name)
    ax.set_title(f"({letter}) t = {t:.1f} s: {what}", fontsize=10)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x, m", fontsize=8)
    ax.set_ylabel("y, m", fontsize=8)
    ax.tick_params(labelsize=8)
    ax.grid(alpha=0.3)
    if letter == "a":
        ax.plot([], [], "x", color="0.3", label="true target")
        ax.plot([], [], "-", color="0.3", lw=1.0, label="path, 4 s either side")
        ax.legend(fontsize=7, loc="lower right")


def _median_over(series: Mapping[int, tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The median over the followers' (t, v) at each time of the longest one;
    a follower counts only within its own times (a killed one's ends early)."""
    grid = max((t for t, _ in series.values()), key=len)
    rows = np.full((len(series), len(grid)), np.nan)
    for k, (t, v) in enumerate(series.values()):
        inside = (grid >= t[0]) & (grid <= t[-1])
        rows[k, inside] = np.interp(grid[inside], t, v)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an instant no follower covers: NaN
        return grid, np.nanmedian(rows, axis=0)


def _swarm_lines(
    ax: Any, drawn: Mapping[int, Series], score: Mapping[int, Any], what: str, unit: str, dt_s: float
) -> None:
    """Over the followers drawn faint: their median (bold black) and the one
    of largest ``score`` (its own colour), each in the legend."""
    grid, median = _median_over({r: (s.t, s.v) for r, s in drawn.items()})
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


# -- formation error (Fig. 6b/d, 7b) ---------------------------------------------------------------


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
        _swarm_lines(ax, drawn, rms, "RMS", "m", ctx.dt_s)
    top, cut = robust_top(arrays)
    ax.set_ylim(0.0, top)
    _time_axis(ax, ctx)
    ax.set_ylabel("distance to its true target, m")
    # Over the whole figure: over the axes alone a long one (a cut recording's) ran past the left edge.
    fig.suptitle(ctx.title("formation_error", "each follower's formation error"), fontsize=11)
    if arrays:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    _time_marks(ax, ctx)
    _cut_note(ax, cut)
    _save(fig, path, dpi)


# -- V_N (Fig. 8) ----------------------------------------------------------------------------------


def vn(path: Any, data: Mapping[str, Series], ctx: Context, dpi: int) -> None:
    import matplotlib.pyplot as plt

    fig, (ax, hist) = plt.subplots(
        1, 2, figsize=(10, 4.2), sharey=True, layout="constrained", gridspec_kw={"width_ratios": [4, 1]}
    )
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
    if not drawn:
        ax.text(0.5, 0.5, "no V_N in this run (l-psi followers have none)", ha="center", transform=ax.transAxes)
        hist.axis("off")
    else:
        lo = min(float(np.min(v)) for _, v in drawn)
        hi = max(float(np.max(v)) for _, v in drawn)
        pad = max(0.05, 0.08 * (hi - lo))
        ax.set_ylim(lo - pad, hi + pad)
        edges = np.linspace(lo - 1e-9, hi + 1e-9, 11) if hi - lo > 1e-6 else np.array([lo - 0.025, lo + 0.025])
        if ctx.many:  # every follower's ticks in one set of bars
            pooled = np.concatenate([v for _, v in drawn])
            share, _ = np.histogram(pooled, bins=edges)
            hist.barh(
                edges[:-1] + 0.5 * np.diff(edges),
                100.0 * share / len(pooled),
                height=0.9 * np.diff(edges),
                color="0.45",
                label=f"all {len(drawn)} followers",
            )
            grid, median = _median_over(averages)
            ax.plot(
                [],
                [],
                lw=0.7,
                color="0.5",
                alpha=0.6,
                label=f"each follower's {VN_SMOOTH_S:g} s moving average ({len(drawn)}), faint",
            )
            ax.plot(
                *gapped(grid, median, ctx.dt_s),
                lw=2.0,
                color="k",
                label=f"median over the {len(drawn)} followers' averages",
            )
        else:
            width = 0.9 * np.diff(edges) / len(drawn)  # the followers' bars side by side in each band
            for k, (r, v) in enumerate(drawn):
                share, _ = np.histogram(v, bins=edges)
                hist.barh(
                    edges[:-1] + (k + 0.55) * width,
                    100.0 * share / len(v),
                    height=width,
                    color=ctx.colour(r),
                    label=f"R{r}",
                )
            ax.plot([], [], lw=0.5, color="0.4", alpha=0.5, label="V_N each tick, as the controller used it")
        hist.set_xlabel("share of ticks, %")
        hist.set_title("time at each V_N", fontsize=9)
        hist.grid(alpha=0.3)
        # Under the figure: inside, it would hide the V_N lines it names.
        ax.figure.legend(*ax.get_legend_handles_labels(), fontsize=8, loc="outside lower center", ncol=3, frameon=False)
    _time_axis(ax, ctx)
    ax.set_ylabel("V_N, m/s")
    note = f"\n{held} ticks holding (V_N = 0) not drawn" if held else ""
    faint = f"each follower's {VN_SMOOTH_S:g} s" if ctx.many else f"every tick; bold: {VN_SMOOTH_S:g} s"
    # Over the whole figure: over the V_N axes alone its lines ran past the figure's left edge.
    ax.figure.suptitle(
        ctx.title("vn", "FIS-2's normal speed V_N") + f"\nfaint: {faint} "
        f"centred moving average, for the eye only (the controller is not filtered){note}",
        fontsize=10,
    )
    _time_marks(ax, ctx, beside=[hist])
    _save(fig, path, dpi)


# -- targets (Fig. 9-10) ---------------------------------------------------------------------------

# The paper's colours (Fig. 9-10): black dots read, green actual, red EKF.
MEASURED, TRUE, EKF = "k", "tab:green", "tab:red"


def _target_rows(ctx: Context, rms: Mapping[int, Any]) -> tuple[list[int], str]:
    """The followers the targets figure shows, and how they were picked (a
    swarm's: the TARGET_ROWS of largest formation error, the worst first)."""
    if not ctx.many:
        return list(ctx.followers), ""
    scored = sorted(ctx.followers, key=lambda r: -rms[r] if isinstance(rms.get(r), (int, float)) else math.inf)
    shown = scored[:TARGET_ROWS]  # the worst first
    return shown, f"\nthe {len(shown)} of the {len(ctx.followers)} followers with the largest formation error"


def targets(
    path: Any,
    data: Mapping[str, Series],
    ctx: Context,
    errors: Mapping[int, Mapping[str, Any]],
    dpi: int,
    rms: Mapping[int, Any] | None = None,
) -> None:
    import matplotlib.pyplot as plt

    shown, which = _target_rows(ctx, rms or {})
    n = max(1, len(shown))
    fig, axes = plt.subplots(
        n, 3, figsize=(14, 4.4 * n), squeeze=False, layout="constrained", gridspec_kw={"width_ratios": [1.0, 1.0, 1.7]}
    )
    for (whole, zoom, err), r in zip(axes, shown, strict=False):
        base = f"/robots/r{r}"
        series = {
            k: data.get(f"{base}/{p}")
            for k, p in (("measured", "target/measured"), ("true", "target/true"), ("ekf", "ekf/target"))
        }
        true = series["true"]
        if true is None or not len(true):
            for ax in (whole, zoom, err):
                ax.axis("off")
            continue
        t_mid = _zoom_time(true, ctx.t_end)
        for ax in (whole, zoom):
            _target_xy(ax, series, ctx.dt_s)
        _xy_limits(whole, true.v, pad=2.0)
        whole.set_title(f"R{r}: virtual target, whole run", fontsize=10)
        sel = np.abs(true.t - t_mid) <= 2.0
        _xy_limits(zoom, true.v[sel], pad=0.6, square=True)
        whole.add_patch(_box(zoom))
        zoom.set_title(f"R{r}: t = {t_mid - 2:.0f}-{t_mid + 2:.0f} s (box on the left)", fontsize=10)
        zoom.legend(fontsize=8, loc="best")
        _target_errors(err, data, base, ctx, errors.get(r) or {})
        err.set_title(f"R{r}: distance to the true target", fontsize=10, pad=14)
    fig.suptitle(
        ctx.title("targets", "virtual target read by the camera (dots), true (green), EKF estimate (red)") + which,
        fontsize=11,
    )
    _save(fig, path, dpi)


def _zoom_time(true: Series, t_end: float) -> float:
    """The middle of the 4 s where the true target turns most (else mid-run)."""
    if len(true) < 10:
        return 0.5 * t_end
    d = np.diff(true.v, axis=0)
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    turn = np.abs(np.gradient(heading))
    k = int(np.argmax(np.convolve(turn, np.ones(40), mode="same")))
    return float(np.clip(true.t[k], 2.0, max(2.0, t_end - 2.0)))


def _target_xy(ax: Any, series: Mapping[str, Series | None], dt_s: float) -> None:
    s = series["measured"]
    if s is not None and len(s):
        ax.scatter(s.v[:, 0], s.v[:, 1], s=4, color=MEASURED, alpha=0.5, lw=0, label="read (eq. 1-2)", zorder=2)
    for key, label, color in (("true", "true", TRUE), ("ekf", "EKF", EKF)):
        s = series[key]
        if s is not None and len(s):
            _, xy = gapped(s.t, s.v, dt_s)
            ax.plot(xy[:, 0], xy[:, 1], lw=1.2, color=color, label=label, zorder=3)
    ax.set_xlabel("x, m")
    ax.set_ylabel("y, m")
    ax.grid(alpha=0.3)


def _xy_limits(ax: Any, pts: np.ndarray, pad: float, square: bool = False) -> None:
    """Equal scales around ``pts`` (the true target, so a wild reading does not
    widen them); a long thin path keeps at least a quarter of its length across."""
    if len(pts) == 0:
        return
    lo, hi = np.percentile(pts, 0.5, axis=0) - pad, np.percentile(pts, 99.5, axis=0) + pad
    centre, span = 0.5 * (lo + hi), hi - lo
    span = np.full(2, float(np.max(span))) if square else np.maximum(span, 0.25 * float(np.max(span)))
    ax.set_xlim(centre[0] - span[0] / 2, centre[0] + span[0] / 2)
    ax.set_ylim(centre[1] - span[1] / 2, centre[1] + span[1] / 2)
    ax.set_aspect("equal", adjustable="box")


def _box(ax: Any) -> Any:
    import matplotlib.patches as mpatches

    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return mpatches.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="0.2", lw=1.0, zorder=5)


def _target_errors(ax: Any, data: Mapping[str, Series], base: str, ctx: Context, rms: Mapping[str, Any]) -> None:
    arrays = []
    for name, label, color in (("measured", "read", MEASURED), ("ekf", "EKF", EKF)):
        s = data.get(f"{base}/error/{name}")
        if s is not None and len(s):
            value = rms.get(f"{name}_rms_m")
            tag = f" (RMS {value:.3f} m)" if isinstance(value, (int, float)) else ""
            ax.plot(
                *gapped(s.t, s.v, ctx.dt_s),
                lw=0.7,
                color=color,
                alpha=0.5 if name == "measured" else 0.9,
                label=label + tag,
            )
            arrays.append(s.v)
    top, cut = robust_top(arrays)
    ax.set_ylim(0.0, top)
    _time_axis(ax, ctx)
    ax.set_ylabel("distance, m")
    if arrays:
        ax.legend(fontsize=8, loc="upper left")
    _time_marks(ax, ctx)
    _cut_note(ax, cut)
