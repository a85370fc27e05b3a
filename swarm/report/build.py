"""Figures and a markdown summary of one run folder, beside the paper's.

Reads RUN_DIR/recording.rrd, summary.json and scenario.toml, and writes into
RUN_DIR/report/ (as PNG, SVG or PDF; a run without its logger has no
recording and gets report.md alone):

    trajectories      paths, obstacles and the formation at each switch (Fig. 6a/c, 7a, 11)
    formation_error   each follower's distance to its true target (Fig. 6b/d, 7b)
    vn                V_N of each follower: every tick and a moving average (Fig. 8)
    targets           true, read and EKF target, and their errors (Fig. 9-10)
    report.md         the run's metrics, formation events, faults and the figures

What each figure shows and why: formation_swarm.report.figures. A title says
"cf. paper Fig. N" only when the run is a shipped scenario as shipped.
"""

from __future__ import annotations

import contextlib
import math
import sys
import tomllib
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from formation_swarm.report import figures
from formation_swarm.report.data import Series, read_folder, robots_in
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser, integer
from formation_swarm.spec.keys import ScenarioWarning

FIGURES = ("trajectories", "formation_error", "vn", "targets")
NO_FIGURES = "no-figures.txt"  # in RUN_DIR/report/ when it could draw none: why
FORMATS = ("png", "svg", "pdf")
DEFAULT_DPI = 150
MAX_SNAPSHOTS = 100
# The paper's figures each shipped scenario reproduces, by figure (scenarios/*.toml).
PAPER = {
    "fig6_turn_vn_1_5": {"trajectories": "Fig. 6a", "formation_error": "Fig. 6b"},
    "fig6_turn_vn_2": {"trajectories": "Fig. 6c", "formation_error": "Fig. 6d"},
    "fig7_turn_vn_dynamic": {"trajectories": "Fig. 7a", "formation_error": "Fig. 7b", "vn": "Fig. 8"},
    "fig9_ekf_noise": {"targets": "Fig. 9-10"},
    "fig11_obstacles": {"trajectories": "Fig. 11"},
}


def make_report(run_dir: str | Path, snapshots: int = 6, fmt: str = "png", dpi: int = DEFAULT_DPI) -> Path:
    """Writes RUN_DIR/report/ and returns it (a folder without recording.rrd:
    report.md alone, saying why). Raises ValueError for a folder it cannot use
    (not a run folder, a recording with no robot in it: a run that ended
    before its first tick) and OSError when it cannot write the report."""
    run_dir = Path(run_dir)
    if not 0 <= snapshots <= MAX_SNAPSHOTS:
        raise ValueError(f"snapshots must be in [0, {MAX_SNAPSHOTS}], got {snapshots!r}")
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    run_dir, summary, data = read_folder(run_dir, need_recording=False)
    rrd = run_dir / "recording.rrd"
    robots = robots_in(data)
    if not robots:  # no recording, or one with nothing in it: the summary's tables alone
        out = run_dir / "report"
        out.mkdir(exist_ok=True)
        followers = sorted(int(r) for r in summary.get("followers") or {} if str(r).isdigit())
        ctx = _context(run_dir, summary, {}, [], followers)  # what the scenario reproduces of the paper
        why = no_recording(summary)  # no logger, or its file gone
        if summary.get("recording") is not None and not summary.get("ticks"):
            why = f"nothing was recorded: {_ended_early(summary)}"
        elif rrd.is_file():
            why = f"its recording holds no robot poses: {_ended_early(summary)}"
        (out / "report.md").write_text(_markdown(summary, followers, ctx=ctx, without=why))
        (out / NO_FIGURES).write_text(why + "\n")
        return out
    with contextlib.suppress(FileNotFoundError):
        (run_dir / "report" / NO_FIGURES).unlink()
    followers = [r for r in robots if f"/robots/r{r}/error/formation" in data]
    import matplotlib

    matplotlib.use("Agg")
    out = run_dir / "report"
    out.mkdir(exist_ok=True)
    ctx = _context(run_dir, summary, data, robots, followers)
    name = {stem: out / f"{stem}.{fmt}" for stem in FIGURES}
    figures.trajectories(name["trajectories"], data, ctx, snapshots, dpi)
    rms = {r: ((summary.get("followers") or {}).get(str(r)) or {}).get("rms_m") for r in followers}
    figures.formation_error(name["formation_error"], data, ctx, rms, dpi)
    figures.vn(name["vn"], data, ctx, dpi)
    errs = ((summary.get("parts") or {}).get("logger") or {}).get("target_errors") or {}
    figures.targets(name["targets"], data, ctx, {r: errs.get(str(r)) or {} for r in followers}, dpi, rms)
    (out / "report.md").write_text(_markdown(summary, followers, fmt, ctx))
    return out


def _context(
    run_dir: Path, summary: Mapping[str, Any], data: Mapping[str, Series], robots: list[int], followers: list[int]
) -> figures.Context:
    """What the figures need from the summary and the scenario as run."""
    from formation_swarm.spec import scenario as scenario_mod

    ctx = figures.Context(
        scenario=str(summary.get("scenario")), seed=summary.get("seed"), robots=robots, followers=followers
    )
    ctx.t_end = max((float(s.t[-1]) for e, s in data.items() if e.endswith("/pose") and len(s)), default=0.0)
    ctx.fault_marks = fault_marks(summary)
    if summary_mod.recording_cut(summary):  # the lines end there; the legends' RMS are the whole run's
        ctx.cut = f"recording cut at {ctx.t_end:.1f} s: the logger was killed"
    ctx.formation_events = [e for e in summary.get("formation_events") or [] if isinstance(e, Mapping)]
    ctx.switches = figures.switches(ctx.formation_events)
    try:
        with warnings.catch_warnings():  # the loader's warnings are the run's: report.md lists them
            warnings.simplefilter("ignore", ScenarioWarning)
            sc = scenario_mod.load(run_dir / "scenario.toml")
    except (OSError, ValueError):
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


def paper_figures(scenario_toml: Path) -> dict[str, str]:
    """The paper's figures this run reproduces, by figure stem: those of the
    shipped scenario it is, with any seed; none if it was changed (a --set,
    a fault) or is not shipped."""
    from formation_swarm.spec.files import shipped

    try:
        raw = tomllib.loads(scenario_toml.read_text())
    except (OSError, ValueError):
        return {}
    for stem, path in shipped().items():
        if stem in PAPER and _without_seed(tomllib.loads(path.read_text())) == _without_seed(raw):
            return dict(PAPER[stem])
    return {}


def paper_changes(scenario_toml: Path) -> str | None:
    """For a run of a paper's scenario that was changed, what was: e.g.
    "fig11_obstacles with [[faults]], run.robots changed" (None: not one)."""
    from formation_swarm.spec.files import shipped

    try:
        raw = _without_seed(tomllib.loads(scenario_toml.read_text()))
    except (OSError, ValueError):
        return None
    for stem, path in shipped().items():
        orig = _without_seed(tomllib.loads(path.read_text()))
        if stem in PAPER and (orig.get("run") or {}).get("name") == (raw.get("run") or {}).get("name"):
            was, now = _flat(orig), _flat(raw)
            changed = sorted(was.keys() ^ now.keys() | {k for k, v in was.items() if k in now and now[k] != v})
            if not changed:
                return None
            shown = ", ".join(changed[:6]) + (f" and {len(changed) - 6} more" if len(changed) > 6 else "")
            return f"{stem} with {shown} changed"
    return None


def _flat(raw: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Dotted keys down to the tables' values; a list of tables ([[faults]]) is one key."""
    out: dict[str, Any] = {}
    for k, v in raw.items():
        if isinstance(v, Mapping):
            out |= _flat(v, f"{prefix}{k}.")
        else:
            out[f"[[{prefix}{k}]]" if isinstance(v, list) and v and isinstance(v[0], Mapping) else f"{prefix}{k}"] = v
    return out


def _without_seed(raw: Mapping[str, Any]) -> dict[str, Any]:
    run = {k: v for k, v in (raw.get("run") or {}).items() if k != "seed"}
    return {**raw, "run": run}


def _stopped_markdown(summary: Mapping[str, Any], followers: list[int]) -> list[str]:
    """A follower whose agent was killed or lost: its figures above include
    the robot standing after that; its error until then."""
    out = []
    events = [e for e in summary.get("events") or [] if isinstance(e, Mapping)]
    for r in followers:
        until = ((summary.get("followers") or {}).get(str(r)) or {}).get("until_stopped")
        if isinstance(until, Mapping):
            fresh = [
                e.get("sim_time_s")
                for e in events
                if e.get("event") == "started" and str(e.get("process", "")).split(".")[0] == f"agent-{r}"
            ]
            back = f", a fresh agent started at t={_num(fresh[0], '.2f')} s" if fresh else ""
            out.append(
                f"R{r} stopped at t={_num(until.get('time_s'), '.2f')} s (its agent killed or lost{back}): its "
                f"figures above include the robot after that; until then RMS {_num(until.get('rms_m'))} m, "
                f"max {_num(until.get('max_m'))} m."
            )
    return out


def _ended_early(summary: Mapping[str, Any]) -> str:
    """Why a run has nothing to draw, from its summary."""
    if not summary.get("ticks"):
        return f"the run ended before its first tick (exit code {summary.get('exit_code')}); see its logs/"
    if cut := summary_mod.recording_cut(summary):
        return cut
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


def _v(x: Any) -> str:
    """A count as written, or "-" where the run has none (it ended before its first tick)."""
    return "-" if x is None else str(x)


def _num(x: Any, fmt: str = ".3f") -> str:
    return "-" if not isinstance(x, (int, float)) or isinstance(x, bool) else format(x, fmt)


def no_recording(summary: Mapping[str, Any]) -> str:
    """Why a run folder has no recording.rrd, for a report made without it."""
    if summary.get("recording") is None:
        return "the run had no logger (--no-logger), so it has no recording"
    return "its recording.rrd is missing from the folder"


def _markdown(
    summary: Mapping[str, Any],
    followers: list[int],
    fmt: str = "png",
    ctx: figures.Context | None = None,
    without: str | None = None,
) -> str:
    """report.md; ``without``: why there are no figures (no recording), said in their place."""
    from formation_swarm.launch.console import losses, rejected_why
    from formation_swarm.runtime.summary import describe_end

    f = _num
    paper = "; ".join(f"{stem} cf. paper {fig}" for stem, fig in (ctx.paper if ctx else {}).items())
    why_not = (ctx.changes if ctx else None) or "not a shipped scenario of the paper"
    lines = [
        f"# Run {summary.get('run_id')}: {summary.get('scenario')}",
        "",
        f"Mode {summary.get('mode')}, seed {summary.get('seed')}, {summary.get('ticks') or 'no'} ticks "
        f"({f(summary.get('sim_time_s'), '.1f')} s simulated), exit code {summary.get('exit_code')}. "
        f"Ended: {summary.get('ended') or describe_end(summary.get('end_reason'), summary.get('ended_at_s'))}.",
        "",
        f"Reproduces: {paper}." if paper else f"Reproduces no figure of the paper as it is ({why_not}).",
        "",
    ]
    if not followers:
        lines += [
            "No follower metrics: "
            + ("the run ended before its first tick." if not summary.get("ticks") else "the run has no follower.")
        ]
    else:
        lines += [
            "| follower | RMS error, m | max, m | RMS in turns, m | RMS on straights, m | mean lag in turns, m "
            "| max ahead of target, m | measured target RMS, m | EKF target RMS, m |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
    errs = ((summary.get("parts") or {}).get("logger") or {}).get("target_errors") or {}
    for r in followers:
        m = (summary.get("followers") or {}).get(str(r)) or {}
        e = errs.get(str(r)) or {}
        if m.get("acquired") is False:
            lines.append(f"| R{r} | never acquired its reference: no metrics |" + " - |" * 7)
            continue
        lines.append(
            f"| R{r} | {f(m.get('rms_m'))} | {f(m.get('max_m'))} | {f(m.get('turn_rms_m'))} | "
            f"{f(m.get('straight_rms_m'))} | {f(m.get('turn_mean_lag_m'))} | {f(m.get('max_ahead_m'))} | "
            f"{f(e.get('measured_rms_m'))} | {f(e.get('ekf_rms_m'))} |"
        )
    lines += [
        "",
        f"Minimum distance between robots {f(summary.get('min_distance_m'))} m "
        f"(diameter {f(summary.get('robot_diameter_m'))} m); collisions {_v(summary.get('collisions'))}, "
        f"with obstacles {_v(summary.get('obstacle_collisions'))}.",
        *_contacts_markdown(summary),
        f"Link layer: {losses(summary)}; lockstep misses {_v(summary.get('lockstep_misses'))}; rejected payloads "
        f"{_v(summary.get('rejected_total'))}{rejected_why(summary)}.",
        *_stopped_markdown(summary, followers),
        *(
            [
                f"**The recording is incomplete:** {summary['recording_gap']}; the target errors measured "
                "from it (the last two columns) miss those ticks."
            ]
            if summary.get("recording_gap")
            else []
        ),
        *([f"**The recording is cut short:** {cut}."] if (cut := summary_mod.recording_cut(summary)) else []),
        "",
        *_warnings_markdown(summary),
        *_events_markdown(summary),
        *_faults_markdown(summary),
        *(
            [f"No figures and no measured or EKF target errors (the last two columns): {without}."]
            if without
            else [f"![{stem}]({stem}.{fmt})" for stem in FIGURES]
        ),
        "",
    ]
    return "\n".join(lines)


def _contacts_markdown(summary: Mapping[str, Any]) -> list[str]:
    """The first contacts, who and when (the world lists the first 50)."""
    from formation_swarm.launch.console import contacts_line

    said = contacts_line(summary.get("contacts") or [], summary.get("collisions"), summary.get("obstacle_collisions"))
    return [said[0].upper() + said[1:] + "."] if said else []


def _warnings_markdown(summary: Mapping[str, Any]) -> list[str]:
    """The scenario loader's warnings for the run, as the console gave them."""
    said = [w for w in summary.get("scenario_warnings") or [] if isinstance(w, str)]
    return ["## Scenario warnings", "", *[f"- {w}" for w in said], ""] if said else []


def _events_markdown(summary: Mapping[str, Any]) -> list[str]:
    """The formation events: each robot's formation code change, by tick."""
    events = [e for e in summary.get("formation_events") or [] if isinstance(e, Mapping)]
    if not events:
        return ["## Formation events", "", "None: the formation never changed.", ""]
    out = ["## Formation events", "", "| tick | time, s | robot | its formation from then |", "|---|---|---|---|"]
    out += [
        f"| {e.get('tick')} | {_num(e.get('time_s'), '.2f')} | R{e.get('robot')} | {e.get('formation')} |"
        for e in events
    ]
    return [*out, ""]


def _faults_markdown(summary: Mapping[str, Any]) -> list[str]:
    """The faults and what they did; processes that exited; robots lost."""
    from formation_swarm.launch.console import describe_counts, describe_event, describe_recoveries

    out: list[str] = []
    faults = [f for f in summary.get("faults") or [] if isinstance(f, Mapping)]
    if faults:
        out += ["## Faults", "", "| fault | ticks (first-last) | what happened | counted |", "|---|---|---|---|"]
        for f in faults:
            start, end = f.get("start_tick"), f.get("end_tick")
            ran = summary.get("ticks")
            if isinstance(start, int) and isinstance(ran, int) and start >= ran:  # as the console says it
                out.append(f"| `{f.get('fault')}` | {start}- | never started: the run ended at tick {ran} | - |")
                continue
            ticks = f"{start}-{end - 1}" if isinstance(end, int) else f"from {start}"
            said = [_fault_event(e) for e in f.get("events") or []] + describe_recoveries(f)
            happened = "; ".join(said) or "-"
            counted = describe_counts(f.get("counts") or {}) or "-"
            if (cut := f.get("counts_partial_for")) and f.get("counts"):
                counted = f"at least {counted} (killed agents' counts end at their last stats write)"
            elif cut:
                counted = f"not counted: {', '.join(f'R{r}' for r in cut)}'s agent killed before it wrote them"
            out.append(f"| `{f.get('fault')}` | {ticks} | {happened} | {counted} |")
        out.append("")
    events = [e for e in summary.get("events") or [] if isinstance(e, Mapping)]
    deaths = [d for d in summary.get("deaths") or [] if isinstance(d, Mapping)]
    if events or deaths:
        out += ["## Processes", ""]
        unexpected = _unexpected_exits(events)
        out += [f"- {describe_event(e)}" for e in events if e.get("event") != "exited" or e in unexpected]
        out += [
            f"- robot {d.get('robot')} lost its agent at tick {d.get('tick')} ({_t(d.get('time_s'))})" for d in deaths
        ]
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
    ap = Parser(
        prog="swarm report",
        description=__doc__,
        epilog="example:\n  swarm run fig11_obstacles --out runs/fig11\n  swarm report runs/fig11",
    )
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
        out = make_report(args.run_dir, args.snapshots, args.format, args.dpi)
    except ValueError as exc:
        print(f"swarm report: {exc}", file=sys.stderr)
        return USAGE_ERROR
    except OSError as exc:
        print(f"swarm report: cannot write the report into {args.run_dir}: {exc}", file=sys.stderr)
        return USAGE_ERROR
    if not (out / NO_FIGURES).is_file():
        print(f"[report] {out}: {', '.join(f'{stem}.{args.format}' for stem in FIGURES)}, report.md")
    else:
        print(f"[report] {out}: report.md only, no figures: {(out / NO_FIGURES).read_text().strip()}")
    return 0
