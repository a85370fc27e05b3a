"""Figures and a markdown summary of one run folder, beside the paper's.

Reads RUN_DIR/recording.rrd, summary.json and scenario.toml, and writes into
RUN_DIR/report/ (as PNG, SVG or PDF; a run without its logger has no
recording and gets report.md alone):

    trajectories      paths, obstacles and the formation at each switch (Fig. 6a/c, 7a, 11)
    formation_error   each follower's distance to its true target (Fig. 6b/d, 7b)
    vn                V_N of each follower: every tick and a moving average (Fig. 8)
    targets           true, read and EKF target, and their errors (Fig. 9-10)
    report.md         the run's metrics, formation events, faults and the figures

What each figure shows and why: formation_swarm.report.figures; what
report.md says: formation_swarm.report.markdown. A title says "cf. paper
Fig. N" only when the run is a shipped scenario as shipped
(formation_swarm.report.paper). The folder's files are checked before
anything is written (formation_swarm.report.inputs); what it refuses and
what it prints: docs/report.md.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import sys
import tempfile
import traceback
from collections.abc import Callable, Mapping
from pathlib import Path

from formation_swarm.report import figures
from formation_swarm.report.data import RunFolder, read_folder, robots_in
from formation_swarm.report.faults import fault_marks
from formation_swarm.report.figures import FIGURES
from formation_swarm.report.markdown import ended_early, no_recording, report_markdown, stopped_early
from formation_swarm.report.paper import paper_changes, paper_figures
from formation_swarm.report.progress import Progress, quiet, say_progress
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser, integer
from formation_swarm.spec.laws import run_laws

NO_FIGURES = "no-figures.txt"  # in RUN_DIR/report/ when it could draw none: why
FORMATS = ("png", "svg", "pdf")
DEFAULT_DPI = 150
MAX_SNAPSHOTS = 100
TRACEBACK_LOG = "report-error.log"  # in RUN_DIR/report/ when swarm report failed: its traceback
EXIT_FAILED = 1  # the report could not be made (not a usage error): one line, the traceback in a log


class UsageError(ValueError):
    """An argument or a run folder that swarm report cannot use (exit code 2)."""


def make_report(
    run_dir: str | Path, snapshots: int = 6, fmt: str = "png", dpi: int = DEFAULT_DPI, progress: Progress | None = None
) -> Path:
    """Writes RUN_DIR/report/ and returns it (a folder without recording.rrd:
    report.md alone, saying why). Raises UsageError for an argument or a
    folder it cannot use (not a run folder; a summary, scenario or recording
    it cannot read or refuses: report.inputs), before writing anything, and
    OSError when it cannot write the report; any other error is its own,
    with a note saying what it was writing. The files are made in a
    temporary folder beside report/ and moved into it once all are made."""
    run_dir = Path(run_dir)
    if not 0 <= snapshots <= MAX_SNAPSHOTS:
        raise UsageError(f"snapshots must be in [0, {MAX_SNAPSHOTS}], got {snapshots!r}")
    if fmt not in FORMATS:
        raise UsageError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    try:
        folder = read_folder(run_dir, need_recording=False)
    except ValueError as exc:  # the folder's own problem, said by the reader
        raise UsageError(str(exc)) from None
    except OSError as exc:  # a file of it this user may not read, say
        raise UsageError(f"cannot read {run_dir}: {exc}") from None
    out = run_dir / "report"
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "not a folder", str(out))
    work = Path(tempfile.mkdtemp(prefix=".report-", dir=run_dir))
    try:
        made = _write(work, folder, snapshots=snapshots, fmt=fmt, dpi=dpi, progress=progress or quiet)
        out.mkdir(exist_ok=True)
        for name in made:
            os.replace(work / name, out / name)
        if NO_FIGURES not in made:
            with contextlib.suppress(FileNotFoundError):
                (out / NO_FIGURES).unlink()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return out


def _write(work: Path, folder: RunFolder, *, snapshots: int, fmt: str, dpi: int, progress: Progress) -> list[str]:
    """The report's files written into ``work``; their names."""
    run_dir, summary, data = folder.run_dir, folder.summary, folder.data
    robots = robots_in(data)
    if not robots:  # no recording, or one with nothing in it: the summary's tables alone
        followers = sorted(int(r) for r in summary.get("followers") or {} if str(r).isdigit())
        ctx = _context(folder, [], followers)  # what the scenario reproduces of the paper
        why = no_recording(summary)  # no logger, or its file gone
        if summary.get("recording") is not None and not summary.get("ticks"):
            why = f"nothing was recorded: {ended_early(summary, run_dir)}"
        elif (run_dir / "recording.rrd").is_file():
            why = f"its recording holds no robot poses: {ended_early(summary, run_dir)}"
        progress("report.md (no figures)")
        (work / "report.md").write_text(report_markdown(summary, followers, ctx=ctx, without=why))
        (work / NO_FIGURES).write_text(why + "\n")
        return ["report.md", NO_FIGURES]
    followers = [r for r in robots if f"/robots/r{r}/error/formation" in data]
    import matplotlib

    matplotlib.use("Agg")
    ctx = _context(folder, robots, followers)
    rms = {r: ((summary.get("followers") or {}).get(str(r)) or {}).get("rms_m") for r in followers}
    errs = ((summary.get("parts") or {}).get("logger") or {}).get("target_errors") or {}
    errors = {r: errs.get(str(r)) or {} for r in followers}
    draw: dict[str, Callable[[Path], None]] = {
        "trajectories": lambda path: figures.trajectories(path, data, ctx, snapshots, dpi),
        "formation_error": lambda path: figures.formation_error(path, data, ctx, rms, dpi),
        "vn": lambda path: figures.vn(path, data, ctx, dpi),
        "targets": lambda path: figures.targets(path, data, ctx, errors, dpi=dpi, rms=rms),
    }
    for k, stem in enumerate(FIGURES, start=1):
        name = f"{stem}.{fmt}"
        progress(f"figure {k}/{len(FIGURES)} {name}")
        try:
            draw[stem](work / name)
        except Exception as exc:
            exc.add_note(f"drawing {name}")
            raise
    progress("report.md")
    (work / "report.md").write_text(report_markdown(summary, followers, fmt, ctx))
    return [*(f"{stem}.{fmt}" for stem in FIGURES), "report.md"]


def _context(folder: RunFolder, robots: list[int], followers: list[int]) -> figures.Context:
    """What the figures need from the summary, the scenario as run and the recording."""
    run_dir, summary, sc, data = folder.run_dir, folder.summary, folder.scenario, folder.data
    ctx = figures.Context(
        scenario=str(summary.get("scenario")), seed=summary.get("seed"), robots=robots, followers=followers
    )
    ctx.t_end = max((float(s.t[-1]) for e, s in data.items() if e.endswith("/pose") and len(s)), default=0.0)
    ctx.fault_marks = fault_marks(summary)
    notes = [stopped_early(summary)]  # said in every title: the lines end early
    if summary_mod.recording_cut(summary):  # the lines end there; the legends' RMS are the whole run's
        events = [e for e in summary.get("events") or [] if e.get("process") == "logger"]
        how = "killed" if any(e.get("event") == "killed" for e in events) else "lost"
        notes.append(f"recording cut at {ctx.t_end:.1f} s: the logger was {how}")
    ctx.cut = "; ".join(n for n in notes if n)
    ctx.formation_events = [e for e in summary.get("formation_events") or [] if isinstance(e, Mapping)]
    ctx.switches = figures.switches(ctx.formation_events)
    if folder.config or summary.get("laws"):  # else not known: not said
        ctx.laws = run_laws(summary, folder.config, followers)
    if sc is None:
        return ctx
    ctx.dt_s, ctx.diameter_m = sc.dt_s, sc.diameter_m
    ctx.obstacles = [(o.x_m, o.y_m, o.radius_m) for o in sc.obstacles]
    ctx.formations = {
        n: {r: (s.reference, (s.offset[0], s.offset[1])) for r, s in f.slots.items()} for n, f in sc.formations.items()
    }
    ctx.start_formation = sc.leader.formation
    ctx.paper = paper_figures(run_dir / "scenario.toml")
    ctx.changes = None if ctx.paper else paper_changes(run_dir / "scenario.toml")
    if ctx.paper and summary.get("end_reason") not in (summary_mod.LEADER_FINISHED, summary_mod.DURATION_REACHED):
        # The paper's scenario, cut short (Ctrl-C, a timeout, a failure): not its figure.
        ctx.paper = {}
        ctx.changes = f"the run did not end as the scenario does: {summary.get('ended') or summary.get('end_reason')}"
    return ctx


def _one_line(exc: BaseException, run_dir: str) -> str:
    """What failed, on one line: what it was doing (its notes) and the error."""
    if isinstance(exc, OSError) and not getattr(exc, "__notes__", None):
        doing = f"cannot write the report into {run_dir}"
    else:
        doing = "; ".join(getattr(exc, "__notes__", None) or ["failed"])
    said = " ".join(str(exc).split()) or "(no message)"
    return f"{doing}: {type(exc).__name__}: {said}"


def _log_traceback(exc: BaseException, folder: Path) -> Path:
    """The traceback of ``exc`` written to folder/TRACEBACK_LOG, or to a file
    of the system's temporary folder where that cannot be written; its path."""
    text = "".join(traceback.format_exception(exc))
    try:
        folder.mkdir(exist_ok=True)
        path = folder / TRACEBACK_LOG
        path.write_text(text)
    except OSError:
        with tempfile.NamedTemporaryFile("w", prefix="swarm-report-", suffix=".log", delete=False) as f:
            f.write(text)
            path = Path(f.name)
    return path


EPILOG = """\
Progress goes to stderr, a line per figure. A summary.json, scenario.toml or
recording.rrd that cannot be read, or that holds what no run writes (wrong
types, NaN or infinite numbers, nesting past 32 levels, a file over the size
limit), is refused before anything is written.

exit codes: 0 the report was written; 1 it could not be (one line on stderr,
the traceback in RUN_DIR/report/report-error.log); 2 a bad command line, or a
folder that is not a run folder or whose files are refused (one line).

example:
  swarm run fig11_obstacles --out runs/fig11
  swarm report runs/fig11"""


def build_parser() -> Parser:
    ap = Parser(prog="swarm report", description=__doc__, epilog=EPILOG)
    ap.add_argument("run_dir", metavar="RUN_DIR", help="a run's folder, as swarm run printed it (runs/<run id>)")
    ap.add_argument(
        "--snapshots",
        type=integer(0, MAX_SNAPSHOTS),
        default=6,
        metavar="N",
        help="for a run with no formation switch, formation snapshots drawn on the trajectory figure, "
        f"evenly spaced from the start to the end, 0 to {MAX_SNAPSHOTS} (default: 6); a run with "
        "switches gets one at each switch and one mid-way through each formation",
    )
    ap.add_argument("--format", choices=FORMATS, default="png", help="the figures' file format (default: png)")
    ap.add_argument(
        "--dpi",
        type=integer(50, 600),
        default=DEFAULT_DPI,
        metavar="N",
        help=f"resolution of PNG figures, 50 to 600 (default: {DEFAULT_DPI})",
    )
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        out = make_report(args.run_dir, args.snapshots, args.format, args.dpi, say_progress("report"))
    except UsageError as exc:
        print(f"swarm report: {exc}", file=sys.stderr)
        return USAGE_ERROR
    except Exception as exc:  # its own error, or the system's: one line here, the traceback in a log
        log = _log_traceback(exc, Path(args.run_dir) / "report")
        print(f"swarm report: {_one_line(exc, args.run_dir)} (traceback in {log})", file=sys.stderr)
        return EXIT_FAILED
    with contextlib.suppress(FileNotFoundError):  # a failure's, before this success
        (out / TRACEBACK_LOG).unlink()
    if not (out / NO_FIGURES).is_file():
        print(f"[report] {out}: {', '.join(f'{stem}.{args.format}' for stem in FIGURES)}, report.md")
    else:
        print(f"[report] {out}: report.md only, no figures: {(out / NO_FIGURES).read_text().strip()}")
    return 0
