"""What ``swarm run`` prints at the end of a run: its metrics and its events.

A run that ended early (no ticks, no metrics) prints what it has; a value
the run did not produce prints as "-", never an error.
"""

from __future__ import annotations

import shutil
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from formation_swarm import summary as summary_mod
from formation_swarm.children import describe_exit

if TYPE_CHECKING:
    from formation_swarm.launcher import RunResult


def _num(value: Any, fmt: str = ".3f") -> str:
    """A number for the console, or "-" for a metric the run did not produce."""
    return format(value, fmt) if isinstance(value, (int, float)) and not isinstance(value, bool) else "-"


def describe_event(ev: Mapping[str, Any]) -> str:
    """One event of the run (a kill, a process that exited, ...) as a sentence."""
    t = ev.get("sim_time_s")
    when = f"at sim t={t:.2f} s" if isinstance(t, (int, float)) and t >= 0 else "before the run started"
    if ev.get("event") == "killed":
        return f"killed {ev.get('process')} {when} (fault injection)"
    if ev.get("event") == "exited" and isinstance(ev.get("code"), int):
        return f"{ev.get('process')} {describe_exit(ev['code'])} {when}"
    return ", ".join(f"{k} {v}" for k, v in ev.items() if k != "log_tail")


def describe_hardware_faults(s: Mapping[str, Any]) -> list[str]:
    """What each sensor and actuator fault did, one line per fault (summary's
    ``sensor_faults`` and ``actuator_faults``)."""
    out = []
    for group in ("sensor_faults", "actuator_faults"):
        for fault, robots in (s.get(group) or {}).items():
            parts = []
            for rid, c in robots.items():
                if group == "sensor_faults":
                    effect = next((k for k in c if k != "ticks"), "")
                    parts.append(
                        f"R{rid} {c.get(effect)} readings {effect.replace('_', ' ')} in {c.get('ticks')} ticks"
                    )
                else:
                    parts.append(f"R{rid} {c.get('ticks')} ticks ({c.get('moving_ticks')} moving)")
            out.append(f"{fault}: {', '.join(parts)}")
    return out


def print_result(res: RunResult, out: TextIO = sys.stdout) -> None:
    """The run's metrics on the console; a run that ended early has fewer (never an error)."""
    s = res.summary
    w = out.write
    ticks = s.get("ticks")
    w(f"run {s.get('run_id')}: exit {res.exit_code}, {ticks if ticks is not None else 'no'} ticks, "
      f"sim {_num(s.get('sim_time_s'), '.2f')} s\n")  # fmt: skip
    w(f"  ended: {summary_mod.describe_end(s.get('end_reason'), s.get('ended_at_s'))}\n")
    if s.get("failure"):
        w(f"  failed: {s['failure']}\n")
    if not ticks:
        w("  no metrics: the run ended before its first tick\n")
    else:
        for rid, m in sorted((s.get("followers") or {}).items()):
            w(f"  follower R{rid}: formation error RMS {_num(m.get('rms_m'))} m, max {_num(m.get('max_m'))} m\n")
        w(f"  min distance {_num(s.get('min_distance_m'))} m (diameter {_num(s.get('robot_diameter_m'), 'g')} m), "
          f"collisions {s.get('collisions')}, obstacle collisions {s.get('obstacle_collisions')}\n")  # fmt: skip
        changes = [f"R{e.get('robot')} {e.get('formation')} at {_num(e.get('time_s'), '.2f')} s"
                   for e in s.get("formation_events") or []]  # fmt: skip
        w(f"  formation changes: {', '.join(changes) or 'none'}\n")
        for line in describe_hardware_faults(s):
            w(f"  fault {line}\n")
        w(f"  lockstep misses {s.get('lockstep_misses')}, drops {s.get('drops_total')}, ")
        w(f"rejected {s.get('rejected_total')}\n")
    events = s.get("events") or []
    killed = {ev.get("process") for ev in events if ev.get("event") == "killed"}
    for ev in events:
        if not (ev.get("event") == "exited" and ev.get("process") in killed):  # the kill said it
            w(f"  event: {describe_event(ev)}\n")
    w(f"run folder: {res.run_dir}\n  summary: {res.run_dir / 'summary.json'}\n")
    if s.get("recording") and res.recording.is_file():
        viewer = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
        w(f"  recording: {res.recording}\n  open it:   {viewer} {res.recording}\n")
