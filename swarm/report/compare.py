"""One figure overlaying several runs: their trajectories and each follower's
formation error over time, run against run.

Each run has its colour, each robot its line style; the legend names each run
by its folder, scenario, seed, the leader's policy and the followers' laws,
and, for runs of one scenario, the keys whose values differ between them.
Reads each RUN_DIR's recording.rrd, summary.json and scenario.toml
(formation_swarm.load_run: a file it refuses is one line, exit 2, and no
figure); progress goes to stderr, a line per run read. A run stopped before
its end (Ctrl-C, its timeout) says so in its legend entry.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from formation_swarm.report.data import RunData, load_run, read_files
from formation_swarm.report.markdown import stopped_early
from formation_swarm.report.progress import Progress, quiet, say_progress
from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser

if TYPE_CHECKING:
    from matplotlib.figure import Figure

MAX_RUNS = 10  # one colour each
FORMATS = ("png", "pdf", "svg")  # the figure's, by --out's suffix
STYLES = ("-", "--", ":", "-.")  # per robot, in the order of their ids (cycled)


def law(run: RunData) -> str:
    """The leader's policy and each follower's law in words (launch.words.describe_laws):
    the run's summary's ``laws``, or for an older summary, from its scenario as run."""
    from formation_swarm.launch.words import describe_laws
    from formation_swarm.spec.laws import run_laws

    return describe_laws(run_laws(run.summary, run.config, run.followers))


def label(run: RunData, differ: Sequence[str] = ()) -> str:
    """The run's folder, scenario, seed and laws, and its values of ``differ``
    (the scenario keys whose values differ between the runs compared) but
    the laws' keys, which the laws say."""
    flat = _flat(run.config)
    shown = [k for k in differ if not LAW_KEY.fullmatch(k)]
    keys = [_said(k, flat.get(k)) for k in shown[:DIFFER_SHOWN]]
    more = f", {len(shown) - DIFFER_SHOWN} more keys differ" if len(shown) > DIFFER_SHOWN else ""
    stopped = f" ({early})" if (early := stopped_early(run.summary)) else ""
    said = f"{run.run_dir.name}{stopped}: {run.scenario}, seed {run.seed}, {law(run)}"
    return said + "".join(f", {k}" for k in keys) + more


DIFFER_SHOWN = 3  # a run's legend entry names at most this many of the keys that differ between the runs
IN_LABEL = ("run.seed", "run.name", "run.description")  # said by label() already
LAW_KEY = re.compile(r"(controller|followers\.\d+)\.(law|vn)")  # a differing key that law() says in the label


def _said(key: str, value: object) -> str:
    """``key=value``; a list or a table by its size (a fault schedule would fill the legend)."""
    if value is None:  # not in this run's scenario: its default
        return f"{key}: none" if key == "faults" else f"{key}: default"
    if isinstance(value, list):
        return f"{key}: {len(value)} entr{'y' if len(value) == 1 else 'ies'}"
    if isinstance(value, dict):
        return f"{key}: {len(value)} keys"
    return f"{key}={value}"


def _flat(table: object, prefix: str = "") -> dict[str, object]:
    """A scenario as run, as dotted keys (leader.speed_mps) -> values."""
    out: dict[str, object] = {}
    if isinstance(table, dict):
        for k, v in table.items():
            out.update(_flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
    return out


def differing(runs: Sequence[RunData]) -> list[str]:
    """The scenario keys (run.seed and the scenario's name aside: the label has them)
    whose values differ between runs of one scenario, sorted (none between scenarios):
    ``controller.law`` and ``followers.N.law`` among them when the laws differ."""
    if len({run.scenario for run in runs}) > 1:
        return []  # different scenarios: their names tell them apart
    flats = [_flat(run.config) for run in runs]
    keys = sorted({k for f in flats for k in f} - set(IN_LABEL))
    return [k for k in keys if len({repr(f.get(k)) for f in flats}) > 1]


def figure(runs: Sequence[RunData]) -> Figure:
    """Trajectories (left) and formation error over time (right) of every run:
    one line per robot per run on the left, per follower per run on the right."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    if not 1 <= len(runs) <= MAX_RUNS:
        raise ValueError(f"compare takes 1 to {MAX_RUNS} runs, got {len(runs)}")
    fig = Figure(figsize=(13, 6.5), layout="constrained")
    traj, err = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1.4]})
    robots = sorted({r for run in runs for r in run.robots})
    style = {r: STYLES[k % len(STYLES)] for k, r in enumerate(robots)}
    for k, run in enumerate(runs):
        color = f"C{k}"
        for i, r in enumerate(run.robots):
            traj.plot(run.pose[i, :, 0], run.pose[i, :, 1], color=color, ls=style[r], lw=1.2)
        for r in run.followers:
            i = run.index(r)
            err.plot(run.time_s, run.formation_error_m[i], color=color, ls=style[r], lw=1.0)
    _obstacles(traj, runs)
    import numpy as np

    from formation_swarm.report.figures import equal_view

    pts = np.concatenate([run.pose[:, :, :2].reshape(-1, 2) for run in runs])
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts):  # equal scales; a long thin path gets a wider view rather than a squashed one (as the report's)
        centre, span = equal_view(pts.min(axis=0), pts.max(axis=0))
        traj.set_xlim(centre[0] - span[0] / 2, centre[0] + span[0] / 2)
        traj.set_ylim(centre[1] - span[1] / 2, centre[1] + span[1] / 2)
    traj.set_aspect("equal", adjustable="box")
    traj.set(xlabel="x, m", ylabel="y, m", title="Trajectories")
    err.set(xlabel="time, s", ylabel="distance to its true target, m", title="Each follower's formation error")
    err.set_ylim(bottom=0)
    for ax in (traj, err):
        ax.grid(alpha=0.3)
    leaders = {r for run in runs for r in run.robots if r not in run.followers}
    robot_keys = [
        Line2D([], [], color="0.2", ls=style[r], label=f"R{r}" + (" (leader)" if r in leaders else "")) for r in robots
    ]
    err.legend(handles=robot_keys, loc="upper right", fontsize=8, title="robot", title_fontsize=8)
    differ = differing(runs)
    run_keys = [Line2D([], [], color=f"C{k}", lw=2.5, label=label(run, differ)) for k, run in enumerate(runs)]
    wide = sum(len(h.get_label()) for h in run_keys) > 150  # side by side they would run off the figure
    fig.legend(handles=run_keys, loc="outside lower center", ncol=1 if wide or len(runs) > 3 else len(runs), fontsize=9)
    fig.suptitle(f"{len(runs)} runs compared")
    return fig


def _obstacles(ax: object, runs: Sequence[RunData]) -> None:
    """Every obstacle of the runs' scenarios, once each (as in the report's figures)."""
    import matplotlib.patches

    from formation_swarm.common.palette import OBSTACLE

    seen = set()
    for run in runs:
        for o in run.config.get("obstacles") or []:
            key = (o.get("x_m"), o.get("y_m"), o.get("radius_m"))
            if None not in key and key not in seen:
                seen.add(key)
                ax.add_patch(matplotlib.patches.Circle(key[:2], key[2], color=OBSTACLE, alpha=0.35, lw=0))  # type: ignore[attr-defined]


def compare(run_dirs: Sequence[str | Path], out: str | Path, progress: Progress | None = None) -> Path:
    """Reads the runs, draws them into ``out`` (PNG, PDF or SVG by its suffix) and returns its path.
    ValueError for a folder it cannot use or a suffix it cannot draw, before anything is written;
    OSError when it cannot write. The figure is written beside ``out`` and renamed to it at the end."""
    path = Path(out)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FORMATS:
        raise ValueError(f"--out {out}: the figure's file ends in {', '.join(f'.{f}' for f in FORMATS)}")
    for d in run_dirs:  # each summary and scenario checked before the first progress line
        read_files(d)
    say = progress or quiet
    runs = []
    for k, d in enumerate(run_dirs, start=1):
        say(f"run {k}/{len(run_dirs)} {d}")
        runs.append(load_run(d))
    say(f"drawing {path.name}")
    fig = figure(runs)
    part = path.with_name(f".{path.name}.part")
    try:
        fig.savefig(part, dpi=110, format=fmt)
        os.replace(part, path)
    finally:
        part.unlink(missing_ok=True)
    return path


def build_parser() -> Parser:
    ap = Parser(
        prog="swarm compare",
        description=__doc__,
        epilog="example:\n  swarm run fig6_turn_vn_1_5 --out runs/static\n"
        "  swarm run fig7_turn_vn_dynamic --out runs/dynamic\n"
        "  swarm compare runs/static runs/dynamic --out static-vs-dynamic.png",
    )
    ap.add_argument(
        "run_dirs",
        nargs="+",
        metavar="RUN_DIR",
        help=f"the run folders to overlay, 1 to {MAX_RUNS}, each as swarm run printed it",
    )
    ap.add_argument(
        "--out",
        default="compare.png",
        metavar="FILE",
        help="the figure to write, PNG, PDF or SVG by its suffix (default: compare.png)",
    )
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if len(args.run_dirs) > MAX_RUNS:
        print(f"swarm compare: at most {MAX_RUNS} runs, got {len(args.run_dirs)}", file=sys.stderr)
        return USAGE_ERROR
    try:
        path = compare(args.run_dirs, args.out, say_progress("compare"))
    except ValueError as exc:
        print(f"swarm compare: {exc}", file=sys.stderr)
        return USAGE_ERROR
    except OSError as exc:
        print(f"swarm compare: cannot write {args.out}: {exc}", file=sys.stderr)
        return USAGE_ERROR
    print(f"[compare] {path.resolve()}")
    return 0
