"""report.md of one run: how it ran and ended, the laws it flew, the
followers' metrics, the collisions and links, the scenario's warnings, the
formation events, the faults and processes, and the figures (or why there
are none)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from formation_swarm.report.faults import faults_markdown
from formation_swarm.report.figures import FIGURES, Context
from formation_swarm.runtime import summary as summary_mod


def report_markdown(
    summary: Mapping[str, Any],
    followers: list[int],
    fmt: str = "png",
    ctx: Context | None = None,
    without: str | None = None,
) -> str:
    """report.md; ``without``: why there are no figures (no recording), said in their place."""
    lines = [
        *_header(summary, ctx),
        *_metrics_table(summary, followers),
        "",
        *_run_notes(summary, followers),
        "",
        *_warnings_markdown(summary),
        *_events_markdown(summary),
        *faults_markdown(summary),
        *(
            [f"No figures and no measured or EKF target errors (the last two columns): {without}."]
            if without
            else [f"![{stem}]({stem}.{fmt})" for stem in FIGURES]
        ),
        "",
    ]
    return "\n".join(lines)


def _header(summary: Mapping[str, Any], ctx: Context | None) -> list[str]:
    """The title, how the run went and ended, and what it reproduces of the paper."""
    from formation_swarm.runtime.summary import describe_end

    paper = "; ".join(f"{stem} cf. paper {fig}" for stem, fig in (ctx.paper if ctx else {}).items())
    why_not = (ctx.changes if ctx else None) or "not a shipped scenario of the paper"
    return [
        f"# Run {summary.get('run_id')}: {summary.get('scenario')}",
        "",
        f"Mode {summary.get('mode')}, seed {summary.get('seed')}, {summary.get('ticks') or 'no'} ticks "
        f"({_num(summary.get('sim_time_s'), '.1f')} s simulated), exit code {summary.get('exit_code')}. "
        f"Ended: {summary.get('ended') or describe_end(summary.get('end_reason'), summary.get('ended_at_s'))}.",
        "",
        *_control(summary, ctx),
        f"Reproduces: {paper}." if paper else f"Reproduces no figure of the paper as it is ({why_not}).",
        "",
    ]


def _control(summary: Mapping[str, Any], ctx: Context | None) -> list[str]:
    """The leader's policy and the followers' laws (spec.laws), when known."""
    from formation_swarm.launch.console import describe_laws

    laws = (ctx.laws if ctx else None) or summary.get("laws")
    return [f"Control: {describe_laws(laws)}.", ""] if isinstance(laws, Mapping) else []


def _metrics_table(summary: Mapping[str, Any], followers: list[int]) -> list[str]:
    """Each follower's errors, or why there are none."""
    f = _num
    if not followers:
        return [
            "No follower metrics: " + ("the run has no follower." if summary.get("ticks") else f"{_no_ticks(summary)}.")
        ]
    lines = [
        "| follower | RMS error, m | max, m | RMS in turns, m | RMS on straights, m | mean lag in turns, m "
        "| max ahead of target, m | measured target RMS, m | EKF target RMS, m | EKF mean NEES (ticks beyond 9.21) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    errs = ((summary.get("parts") or {}).get("logger") or {}).get("target_errors") or {}
    for r in followers:
        m = (summary.get("followers") or {}).get(str(r)) or {}
        e = errs.get(str(r)) or {}
        if m.get("acquired") is False:
            lines.append(f"| R{r} | never acquired its reference: no metrics |" + " - |" * 8)
            continue
        lines.append(
            f"| R{r} | {f(m.get('rms_m'))} | {f(m.get('max_m'))} | {f(m.get('turn_rms_m'))} | "
            f"{f(m.get('straight_rms_m'))} | {f(m.get('turn_mean_lag_m'))} | {f(m.get('max_ahead_m'))} | "
            f"{f(e.get('measured_rms_m'))} | {f(e.get('ekf_rms_m'))} | {_nees(e)} |"
        )
    return lines


def _nees(e: Mapping[str, Any]) -> str:
    """The EKF's mean NEES (2 for a consistent filter of the 2-D target) and the share of
    its ticks beyond chi-square(2)'s 99% point, 9.21 (1% for a consistent filter)."""
    if e.get("nees_mean") is None:
        return "-"
    beyond = e.get("nees_beyond_99")
    return f"{e['nees_mean']:.2f}" + ("" if beyond is None else f" ({beyond:.1%})")


def _run_notes(summary: Mapping[str, Any], followers: list[int]) -> list[str]:
    """Distances and collisions, the link layer, robots stopped, a recording incomplete or cut."""
    from formation_swarm.launch.console import losses, rejected_why

    f = _num
    lines = [
        f"Minimum distance between robots {f(summary.get('min_distance_m'))} m "
        f"(diameter {f(summary.get('robot_diameter_m'))} m); collisions {_v(summary.get('collisions'))}, "
        f"with obstacles {_v(summary.get('obstacle_collisions'))}.",
        *_contacts_markdown(summary),
        f"Link layer: {losses(summary)}; lockstep misses {_v(summary.get('lockstep_misses'))}; rejected payloads "
        f"{_v(summary.get('rejected_total'))}{rejected_why(summary)}.",
        *_stopped_markdown(summary, followers),
    ]
    if summary.get("recording_gap"):
        lines.append(
            f"**The recording is incomplete:** {summary['recording_gap']}; the target errors measured "
            "from it (the last two columns) miss those ticks."
        )
    if cut := summary_mod.recording_cut(summary):
        lines.append(f"**The recording is cut short:** {cut}.")
    return lines


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


def no_recording(summary: Mapping[str, Any]) -> str:
    """Why a run folder has no recording.rrd, for a report made without it."""
    if summary.get("recording") is None:
        return "the run had no logger (--no-logger), so it has no recording"
    return "its recording.rrd is missing from the folder"


def ended_early(summary: Mapping[str, Any], run_dir: Path) -> str:
    """Why a run has nothing to draw, from its summary, pointing to the
    logs that ``run_dir`` holds (or saying what it holds)."""
    if not summary.get("ticks"):
        return f"{_no_ticks(summary)} (exit code {summary.get('exit_code')}); {_see_logs(run_dir)}"
    if cut := summary_mod.recording_cut(summary):
        return cut
    log = run_dir / "logs" / "logger.log"
    return "the logger recorded none" + (" (see logs/logger.log)" if log.is_file() else f"; {_see_logs(run_dir)}")


def _see_logs(run_dir: Path) -> str:
    """Where to look: its logs/, or, when it has none, what the folder holds."""
    if (run_dir / "logs").is_dir():
        return "see its logs/"
    mine = [p for p in run_dir.iterdir() if p.name != "report" and not p.name.startswith(".")]  # not the report's
    held = sorted(p.name + ("/" if p.is_dir() else "") for p in mine)
    return f"it has no logs/ (the folder holds {', '.join(held[:8]) or 'nothing'}{', ...' if len(held) > 8 else ''})"


def stopped_early(summary: Mapping[str, Any]) -> str | None:
    """A run stopped from outside before its end (Ctrl-C, a signal, its
    timeout), as every figure's title says it: "interrupted at 3.0 s"."""
    reason = summary.get("end_reason")
    if reason == summary_mod.TIMED_OUT or (reason is None and summary.get("timed_out")):
        what = "stopped by its timeout"
    elif reason == summary_mod.INTERRUPTED or (reason is None and summary.get("interrupted")):
        what = "interrupted"
    else:
        return None
    at = summary.get("ended_at_s")
    at = at if isinstance(at, (int, float)) else summary.get("sim_time_s")
    return f"{what} at {at:.1f} s" if isinstance(at, (int, float)) and not isinstance(at, bool) else what


def _no_ticks(summary: Mapping[str, Any]) -> str:
    """Why a summary has no ticks: the run never had one, or the world wrote no stats after it had."""
    seen = summary.get("ticks_seen")
    if isinstance(seen, int):
        return f"the world wrote no metrics (the run had reached tick {seen})"
    if early := stopped_early(summary):  # "interrupted", without its time: 0 s or none
        return f"the run was {early.partition(' at ')[0]} before its first tick"
    return "the run ended before its first tick"


def _v(x: Any) -> str:
    """A count as written, or "-" where the run has none (it ended before its first tick)."""
    return "-" if x is None else str(x)


def _num(x: Any, fmt: str = ".3f") -> str:
    return "-" if not isinstance(x, (int, float)) or isinstance(x, bool) else format(x, fmt)
