"""A run's faults and its processes' exits as the report gives them: marks
on the figures' time axes and the Faults and Processes sections of
report.md."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any


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
    for ev in unexpected_exits(events):
        t = ev.get("sim_time_s")
        if isinstance(t, (int, float)) and t >= 0:
            marks.append((float(t), None, f"{ev.get('process')} exited"))
    return marks


def unexpected_exits(events: list[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The exits that no fault caused (a killed process's exit was the fault's doing)."""
    caused = {ev.get("process") for ev in events if ev.get("event") in ("killed", "restarted")}
    return [ev for ev in events if ev.get("event") == "exited" and ev.get("process") not in caused]


def faults_markdown(summary: Mapping[str, Any]) -> list[str]:
    """The faults and what they did; processes that exited; robots lost."""
    faults = [f for f in summary.get("faults") or [] if isinstance(f, Mapping)]
    out: list[str] = []
    if faults:
        out += ["## Faults", "", "| fault | ticks (first-last) | what happened | counted |", "|---|---|---|---|"]
        out += [_fault_row(f, summary.get("ticks")) for f in faults]
        out.append("")
    return out + _processes_markdown(summary)


def _fault_row(f: Mapping[str, Any], ran: Any) -> str:
    """One fault's row: its ticks, what it did and what it counted (``ran``: the run's ticks)."""
    from formation_swarm.launch.console import describe_counts, describe_recoveries

    start, end = f.get("start_tick"), f.get("end_tick")
    if isinstance(start, int) and isinstance(ran, int) and start >= ran:  # as the console says it
        return f"| `{f.get('fault')}` | {start}- | never started: the run ended at tick {ran} | - |"
    ticks = f"{start}-{end - 1}" if isinstance(end, int) else f"from {start}"
    said = [_fault_event(e) for e in f.get("events") or []] + describe_recoveries(f)
    happened = "; ".join(said) or "-"
    counted = describe_counts(f.get("counts") or {}) or "-"
    if (cut := f.get("counts_partial_for")) and f.get("counts"):
        counted = f"at least {counted} (killed agents' counts end at their last stats write)"
    elif cut:
        counted = f"not counted: {', '.join(f'R{r}' for r in cut)}'s agent killed before it wrote them"
    return f"| `{f.get('fault')}` | {ticks} | {happened} | {counted} |"


def _processes_markdown(summary: Mapping[str, Any]) -> list[str]:
    """Processes that started, were killed or exited on their own; robots that lost their agent."""
    from formation_swarm.launch.console import describe_event

    events = [e for e in summary.get("events") or [] if isinstance(e, Mapping)]
    deaths = [d for d in summary.get("deaths") or [] if isinstance(d, Mapping)]
    if not events and not deaths:
        return []
    out = ["## Processes", ""]
    unexpected = unexpected_exits(events)
    out += [f"- {describe_event(e)}" for e in events if e.get("event") != "exited" or e in unexpected]
    out += [f"- robot {d.get('robot')} lost its agent at tick {d.get('tick')} ({_t(d.get('time_s'))})" for d in deaths]
    if summary.get("failure"):
        out.append(f"- the run failed: {summary['failure']}")
    out.append("")
    return out


def _fault_event(e: Mapping[str, Any]) -> str:
    robot = f" R{e['robot']}" if e.get("robot") is not None else ""
    return f"{e.get('event')}{robot} at tick {e.get('tick')} ({_t(e.get('time_s'))})"


def _t(x: Any) -> str:
    return f"{x:.2f} s" if isinstance(x, (int, float)) and not isinstance(x, bool) else "-"
