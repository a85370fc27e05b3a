"""The targets figure (Fig. 9-10): per follower, its virtual target as the
camera read it, as the EKF estimated it and as it truly was, over the whole
run and zoomed on its sharpest turn, and the distance of each to the truth."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from formation_swarm.report.figures import drawing
from formation_swarm.report.figures.context import Context
from formation_swarm.report.figures.series import Series, gapped, robust_top

# The paper's colours (Fig. 9-10): black dots read, green actual, red EKF.
MEASURED, TRUE, EKF = "k", "tab:green", "tab:red"
# A swarm's targets figure shows the TARGET_ROWS followers of largest formation error.
TARGET_ROWS = 4


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
    *,
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
    drawing.save(fig, path, dpi)


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
    drawing.time_axis(ax, ctx)
    ax.set_ylabel("distance, m")
    if arrays:
        ax.legend(fontsize=8, loc="upper left")
    drawing.time_marks(ax, ctx)
    drawing.cut_note(ax, cut)
