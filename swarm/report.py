"""Figures and a markdown summary of one run folder, in the spirit of the paper.

Reads RUN_DIR/recording.rrd (so the run needs its logger) and summary.json,
and writes into RUN_DIR/report/:

    trajectories.png      paths, obstacles and formation snapshots (Fig. 6a/c, 7a, 11)
    formation_error.png   each follower's distance to its true target (Fig. 6b/d, 7b)
    vn.png                V_N of each follower (Fig. 8)
    targets.png           true, measured and EKF target, and their errors (Fig. 9-10)
    report.md             the run's metrics and the figures
"""

from __future__ import annotations

import json
import math
import sys
import warnings
from collections import defaultdict
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from formation_swarm.cliargs import USAGE_ERROR, Parser, integer
from formation_swarm.palette import robot_colour

FIGURES = ("trajectories.png", "formation_error.png", "vn.png", "targets.png")
MAX_SNAPSHOTS = 100


class Series:
    """One entity's rows from the recording: times (s) and values, time-sorted."""

    def __init__(self, t: np.ndarray, v: np.ndarray) -> None:
        order = np.argsort(t, kind="stable")
        self.t, self.v = t[order], v[order]

    def __len__(self) -> int:
        return len(self.t)


def read_recording(path: Path) -> dict[str, Series]:
    """Every point and scalar entity of a recording, by entity path."""
    from rerun.chunk import RrdReader

    times: dict[str, list[np.ndarray]] = defaultdict(list)
    values: dict[str, list[np.ndarray]] = defaultdict(list)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a recording cut by a kill has no footer: still readable
        chunks = list(RrdReader(str(path)).stream())
    for ch in chunks:
        rb = ch.to_record_batch()
        names = rb.schema.names
        if "sim_time" not in names:
            continue
        col = next((n for n in ("Points2D:positions", "Scalars:scalars") if n in names), None)
        if col is None:
            continue
        t = rb.column("sim_time").cast("int64").to_numpy(zero_copy_only=False) / 1e9
        rows = rb.column(col).to_pylist()
        keep = [i for i, r in enumerate(rows) if r]
        entity = str(ch.entity_path)
        times[entity].append(t[keep])
        values[entity].append(np.array([r[0] for i, r in enumerate(rows) if r], dtype=float))
    return {e: Series(np.concatenate(times[e]), np.concatenate(values[e])) for e in times}


def robots_in(data: Mapping[str, Series]) -> list[int]:
    ids = {int(e.split("/")[2][1:]) for e in data if e.startswith("/robots/r") and e.endswith("/pose")}
    return sorted(ids)


def make_report(run_dir: str | Path, snapshots: int = 6) -> Path:
    """Writes RUN_DIR/report/ and returns it. Raises ValueError for a folder it
    cannot use (not a run folder, no recording, a run that ended before its
    first tick) and OSError when it cannot write the report."""
    run_dir = Path(run_dir)
    if not 0 <= snapshots <= MAX_SNAPSHOTS:
        raise ValueError(f"snapshots must be in [0, {MAX_SNAPSHOTS}], got {snapshots!r}")
    summary_path, rrd = run_dir / "summary.json", run_dir / "recording.rrd"
    if not run_dir.is_dir():
        raise ValueError(f"{run_dir}: no such folder")
    if not summary_path.is_file():
        raise ValueError(f"{run_dir} is not a run folder: no summary.json")
    try:
        summary = json.loads(summary_path.read_text())
    except ValueError as exc:
        raise ValueError(f"{summary_path} is not valid JSON: {exc}") from None
    if not isinstance(summary, dict):
        raise ValueError(f"{summary_path} is not a run summary (a JSON object)")
    if not rrd.is_file():
        raise ValueError(f"{run_dir} has no recording.rrd: run it with its logger (without --no-logger)")
    try:
        data = read_recording(rrd)
    except RuntimeError as exc:  # rerun's reader: a file cut before its first chunk, or not a recording
        raise ValueError(f"cannot read {rrd}: {exc}") from None
    robots = robots_in(data)
    if not robots:
        raise ValueError(f"{rrd} holds no robot poses: " + _ended_early(summary))
    followers = [r for r in robots if f"/robots/r{r}/error/formation" in data]
    import matplotlib

    matplotlib.use("Agg")
    out = run_dir / "report"
    out.mkdir(exist_ok=True)
    obstacles = _obstacles(run_dir)
    _trajectories(out / "trajectories.png", data, robots, followers, obstacles, snapshots, summary)
    marks = fault_marks(summary)
    _over_time(out / "formation_error.png", data, followers, "error/formation", "distance to target, m",
               "Formation error (Fig. 6b/d, 7b)", marks)  # fmt: skip
    _over_time(out / "vn.png", data, followers, "fis/v_n", "V_N, m/s", "Normal speed V_N (Fig. 8)", marks)
    _targets(out / "targets.png", data, followers, marks)
    (out / "report.md").write_text(_markdown(summary, followers))
    return out


def _ended_early(summary: Mapping[str, Any]) -> str:
    """Why a run has nothing to draw, from its summary."""
    if not summary.get("ticks"):
        return f"the run ended before its first tick (exit code {summary.get('exit_code')}); see its logs/"
    return "the logger recorded none (see logs/logger.log)"


def fault_marks(summary: Mapping[str, Any]) -> list[tuple[float, float | None, str]]:
    """What to mark on the time axes: (start s, end s or None for an instant,
    label) for every scheduled fault and every process that exited on its own."""
    marks: list[tuple[float, float | None, str]] = []
    for f in summary.get("faults") or []:
        if not isinstance(f, Mapping) or not isinstance(f.get("at_s"), (int, float)):
            continue
        start = float(f["at_s"])
        label = f"{f.get('kind')} {f.get('target')}"
        end = None
        if f.get("kind") == "restart":
            back = [e.get("time_s") for e in f.get("events") or [] if e.get("event") == "rejoined"]
            end = back[0] if back and isinstance(back[0], (int, float)) else None
        elif isinstance(f.get("for_s"), (int, float)):
            end = start + float(f["for_s"])
        elif f.get("kind") != "kill":
            end = math.inf  # to the end of the run
        marks.append((start, end, label))
    events = [ev for ev in summary.get("events") or [] if isinstance(ev, Mapping)]
    for ev in _unexpected_exits(events):
        t = ev.get("sim_time_s")
        if isinstance(t, (int, float)) and t >= 0:
            marks.append((float(t), None, f"{ev.get('process')} exited"))
    return marks


def _unexpected_exits(events: list[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The exits that no fault caused (a killed process's exit was the fault's doing)."""
    caused = {ev.get("process") for ev in events if ev.get("event") in ("killed", "restarted")}
    return [ev for ev in events if ev.get("event") == "exited" and ev.get("process") not in caused]


def _mark(ax: Any, marks: list[tuple[float, float | None, str]]) -> None:
    """Shade fault windows and draw instants, each labelled at the top of the axes."""
    if not marks:
        return
    lo, hi = ax.get_xlim()
    for k, (start, end, label) in enumerate(marks):
        color = f"C{(k + 3) % 10}"
        if end is None:
            ax.axvline(start, color=color, lw=1.2, ls="--")
        else:
            ax.axvspan(start, min(end, hi), color=color, alpha=0.15, lw=0)
        ax.text(start, 0.98, f" {label}", transform=ax.get_xaxis_transform(), rotation=90, va="top", ha="left",
                fontsize=8, color=color, zorder=5,
                bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "none", "pad": 1.0})  # fmt: skip
    ax.set_xlim(lo, hi)


def _obstacles(run_dir: Path) -> list[tuple[float, float, float]]:
    from formation_swarm import scenario as scenario_mod

    try:
        sc = scenario_mod.load(run_dir / "scenario.toml")
    except (OSError, ValueError):
        return []
    return [(o.x_m, o.y_m, o.radius_m) for o in sc.obstacles]


def _trajectories(path: Path, data: Mapping[str, Series], robots: list[int], followers: list[int],
                  obstacles: list[tuple[float, float, float]], snapshots: int,
                  summary: Mapping[str, Any]) -> None:  # fmt: skip
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 7))
    for x, y, r in obstacles:
        ax.add_patch(plt.Circle((x, y), r, color="tab:red", alpha=0.4))
    poses = {r: data[f"/robots/r{r}/pose"] for r in robots}
    for r, s in poses.items():
        ax.plot(s.v[:, 0], s.v[:, 1], lw=1.2, color=robot_colour(r),
                label=f"R{r}" + (" (leader)" if r not in followers else ""))  # fmt: skip
    leader = next(r for r in robots if r not in followers) if len(followers) < len(robots) else robots[0]
    t_end = poses[leader].t[-1] if len(poses[leader]) else 0.0
    for k, ts in enumerate(np.linspace(0.0, t_end, snapshots)):  # from the start to the end
        pts = {r: s.v[min(np.searchsorted(s.t, ts), len(s) - 1)] for r, s in poses.items() if len(s)}
        xs = [pts[r][0] for r in sorted(pts)] + [pts[sorted(pts)[0]][0]]
        ys = [pts[r][1] for r in sorted(pts)] + [pts[sorted(pts)[0]][1]]
        ax.plot(xs, ys, color="0.4", lw=0.8, ls="--", label="formation snapshots" if k == 0 else None)
        ax.scatter([p[0] for p in pts.values()], [p[1] for p in pts.values()], s=14, color="k", zorder=3)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x, m")
    ax.set_ylabel("y, m")
    ax.set_title(f"{summary.get('scenario', '')}: trajectories (Fig. 6a/c, 7a, 11)")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _over_time(path: Path, data: Mapping[str, Series], followers: list[int], entity: str, ylabel: str,
               title: str, marks: list[tuple[float, float | None, str]] = ()) -> None:  # fmt: skip
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.5))
    for r in followers:
        s = data.get(f"/robots/r{r}/{entity}")
        if s is not None and len(s):
            ax.plot(s.t, s.v, lw=1.0, color=robot_colour(r), label=f"R{r}")
    ax.set_xlabel("time, s")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if ax.lines:
        ax.legend(fontsize=8, loc="upper right")
        _mark(ax, list(marks))
    else:
        ax.text(0.5, 0.5, "no data (l-psi followers have no V_N)", ha="center", transform=ax.transAxes)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _targets(path: Path, data: Mapping[str, Series], followers: list[int],
             marks: list[tuple[float, float | None, str]] = ()) -> None:  # fmt: skip
    import matplotlib.pyplot as plt

    n = max(1, len(followers))
    fig, axes = plt.subplots(n, 2, figsize=(11, 4 * n), squeeze=False)
    for row, r in zip(axes, followers, strict=False):
        base = f"/robots/r{r}"
        xy, err = row
        s = data.get(f"{base}/target/measured")
        if s is not None and len(s):
            xy.scatter(s.v[:, 0], s.v[:, 1], s=3, alpha=0.35, color="tab:orange", label="measured")
        for name, label, color in (("target/true", "true", "k"), ("ekf/target", "EKF", "tab:blue")):
            s = data.get(f"{base}/{name}")
            if s is not None and len(s):
                xy.plot(s.v[:, 0], s.v[:, 1], lw=1.0, color=color, label=label)
        xy.set_aspect("equal", adjustable="datalim")
        xy.set_title(f"R{r}: virtual target (Fig. 9)")
        xy.legend(fontsize=8)
        xy.grid(alpha=0.3)
        for name, label, color in (("error/measured", "measured", "tab:orange"), ("error/ekf", "EKF", "tab:blue")):
            s = data.get(f"{base}/{name}")
            if s is not None and len(s):
                rms = math.sqrt(float(np.mean(s.v**2)))
                err.plot(s.t, s.v, lw=0.8, color=color, label=f"{label} (RMS {rms:.3f} m)")
        err.set_title(f"R{r}: target error vs the true target (Fig. 10)")
        err.set_xlabel("time, s")
        err.set_ylabel("m")
        err.legend(fontsize=8, loc="upper right")
        _mark(err, list(marks))
        err.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _markdown(summary: Mapping[str, Any], followers: list[int]) -> str:
    def f(x: Any, fmt: str = ".3f") -> str:
        return "-" if not isinstance(x, (int, float)) or isinstance(x, bool) else format(x, fmt)

    lines = [
        f"# Run {summary.get('run_id')}: {summary.get('scenario')}",
        "",
        f"Mode {summary.get('mode')}, seed {summary.get('seed')}, {summary.get('ticks')} ticks "
        f"({f(summary.get('sim_time_s'), '.1f')} s simulated), exit code {summary.get('exit_code')}.",
        "",
        "| follower | RMS error, m | max, m | RMS in turns, m | RMS on straights, m | mean lag in turns, m "
        "| max ahead of target, m | measured target RMS, m | EKF target RMS, m |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    errs = ((summary.get("parts") or {}).get("logger") or {}).get("target_errors") or {}
    for r in followers:
        m = (summary.get("followers") or {}).get(str(r)) or {}
        e = errs.get(str(r)) or {}
        lines.append(
            f"| R{r} | {f(m.get('rms_m'))} | {f(m.get('max_m'))} | {f(m.get('turn_rms_m'))} | "
            f"{f(m.get('straight_rms_m'))} | {f(m.get('turn_mean_lag_m'))} | {f(m.get('max_ahead_m'))} | "
            f"{f(e.get('measured_rms_m'))} | {f(e.get('ekf_rms_m'))} |"
        )
    events = ", ".join(f"R{e.get('robot')} {e.get('formation')} at {f(e.get('time_s'), '.2f')} s"
                       for e in summary.get("formation_events") or []) or "none"  # fmt: skip
    lines += [
        "",
        f"Minimum distance between robots {f(summary.get('min_distance_m'))} m "
        f"(diameter {f(summary.get('robot_diameter_m'))} m); collisions {summary.get('collisions')}, "
        f"with obstacles {summary.get('obstacle_collisions')}.",
        f"Formation changes: {events}.",
        f"Messages dropped by the link layer: {summary.get('drops_total')}; lockstep misses "
        f"{summary.get('lockstep_misses')}; rejected payloads {summary.get('rejected_total')}.",
        "",
        *_faults_markdown(summary),
        *[f"![{name[:-4]}]({name})" for name in FIGURES],
        "",
    ]
    return "\n".join(lines)


def _faults_markdown(summary: Mapping[str, Any]) -> list[str]:
    """The faults and what they did; processes that exited; robots lost."""
    from formation_swarm.console import describe_event

    out: list[str] = []
    faults = [f for f in summary.get("faults") or [] if isinstance(f, Mapping)]
    if faults:
        out += ["## Faults", "", "| fault | ticks | what happened | counted |", "|---|---|---|---|"]
        for f in faults:
            end = f.get("end_tick")
            ticks = f"{f.get('start_tick')}-{end}" if end is not None else f"from {f.get('start_tick')}"
            happened = "; ".join(_fault_event(e) for e in f.get("events") or []) or "-"
            counted = ", ".join(f"{k} {v}" for k, v in sorted((f.get("counts") or {}).items())) or "-"
            out.append(f"| `{f.get('fault')}` | {ticks} | {happened} | {counted} |")
        out.append("")
    events = [e for e in summary.get("events") or [] if isinstance(e, Mapping)]
    deaths = [d for d in summary.get("deaths") or [] if isinstance(d, Mapping)]
    if events or deaths:
        out += ["## Processes", ""]
        unexpected = _unexpected_exits(events)
        out += [f"- {describe_event(e)}" for e in events if e.get("event") != "exited" or e in unexpected]
        out += [f"- robot {d.get('robot')} lost its agent at tick {d.get('tick')} ({_t(d.get('time_s'))})"
                for d in deaths]  # fmt: skip
        if summary.get("failure"):
            out.append(f"- the run failed: {summary['failure']}")
        out.append("")
    return out


def _fault_event(e: Mapping[str, Any]) -> str:
    robot = f" R{e['robot']}" if e.get("robot") is not None else ""
    return f"{e.get('event')}{robot} at tick {e.get('tick')} ({_t(e.get('time_s'))})"


def _t(x: Any) -> str:
    return f"{x:.2f} s" if isinstance(x, (int, float)) and not isinstance(x, bool) else "-"


def build_parser() -> Parser:
    ap = Parser(prog="swarm report", description=__doc__,
                epilog="example:\n  swarm run fig11_obstacles --out runs/fig11\n  swarm report runs/fig11")  # fmt: skip
    ap.add_argument("run_dir", metavar="RUN_DIR", help="a run's folder, as swarm run printed it (runs/<run id>)")
    ap.add_argument("--snapshots", type=integer(0, MAX_SNAPSHOTS), default=6, metavar="N",
                    help="formation snapshots drawn on the trajectory figure, evenly spaced in time from the start "
                    f"to the end, 0 to {MAX_SNAPSHOTS} (default: 6)")  # fmt: skip
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        out = make_report(args.run_dir, args.snapshots)
    except ValueError as exc:
        print(f"swarm report: {exc}", file=sys.stderr)
        return USAGE_ERROR
    except OSError as exc:
        print(f"swarm report: cannot write the report into {args.run_dir}: {exc}", file=sys.stderr)
        return USAGE_ERROR
    print(f"[report] {out}: {', '.join(FIGURES)}, report.md")
    return 0
