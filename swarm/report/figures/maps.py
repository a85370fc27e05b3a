"""The trajectories figure (Fig. 6a/c, 7a, 11): every robot's path on the
plane with the obstacles, the formation drawn at chosen times, and those
snapshots zoomed in, one panel each."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from formation_swarm.report.figures import drawing
from formation_swarm.report.figures.context import Context
from formation_swarm.report.figures.series import Series

LETTERS = "abcdefghijklmnopqrstuvwxyz"  # panel letters, as the paper's Fig. 11 (a-d)
MAX_PANELS = 9  # zoomed snapshots on the trajectory figure
MIN_HELD_S = 2.0  # a formation flown shorter than this gets no mid-way snapshot
NARROW_VIEW_IN = 3.5  # a trajectory view narrower than this gets its legend beside it, not over it
LEGEND_WIDTH_IN = 3.0  # what a swarm's trajectory figure without zoomed panels grows by, for its legend beside it
NAMED_EVERY = 5  # on a zoomed snapshot of many robots: the leader and every 5th robot are named
SNAPSHOT_GAP_M = 1.0  # kept snapshots' boxes are at least this far apart


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
    _overview(over, poses, ctx, snaps, (lo, hi))
    for k, (ax, snap) in enumerate(zip(panels, zoomed, strict=True)):
        _zoom(ax, data, poses, ctx, snap, letter=LETTERS[k])
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
    fig.suptitle(ctx.title("trajectories", "trajectories") + f"\n{_how(ctx, snaps, zoomed, evenly)}", fontsize=11)
    drawing.save(fig, path, dpi)


def _how(ctx: Context, snaps: Sequence[tuple[float, str]], zoomed: Sequence[tuple[float, str]], evenly: int) -> str:
    """What the snapshots are, for the title."""
    if zoomed:
        last = LETTERS[len(zoomed) - 1]
        return f"snapshots (black) at each formation switch and mid-way through each formation, zoomed in (a)-({last})"
    if len(snaps) < evenly:
        times = ", ".join(f"{t:.1f}" for t, _ in snaps)
        return f"formation at {times} s (no formation switch; overlapping ones left out)"
    return f"formation every {ctx.t_end / max(1, evenly - 1):.1f} s (no formation switch)"


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
    ax: Any,
    poses: Mapping[int, Series],
    ctx: Context,
    snaps: list[tuple[float, str]],
    extent: tuple[np.ndarray, np.ndarray],
) -> None:
    """The whole run on one panel: paths, obstacles and the formation at each
    snapshot, labelled, in a view of the data's ``extent`` (low, high corner)."""
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
    centre, span = equal_view(*extent)
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


def _links(ax: Any, ctx: Context, pts: Mapping[int, np.ndarray], t: float, *, lw: float, label: str | None) -> None:
    """Each follower joined to its reference in the formation it flies at ``t``."""
    for r in ctx.followers:
        slot = ctx.formations.get(ctx.flown(r, t) or "", {}).get(r)
        if slot is None or r not in pts or slot[0] not in pts:
            continue
        (x0, y0), (x1, y1) = pts[slot[0]], pts[r]
        ax.plot([x0, x1], [y0, y1], color="0.25", lw=lw, ls="--", zorder=3, label=label)
        label = None


def _zoom(
    ax: Any,
    data: Mapping[str, Series],
    poses: Mapping[int, Series],
    ctx: Context,
    snap: tuple[float, str],
    *,
    letter: str,
) -> None:
    """One snapshot (time, kind) zoomed in: the robots at their size, their
    paths 4 s either side, the formation's links and the true targets."""
    import matplotlib.pyplot as plt

    t, kind = snap
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
