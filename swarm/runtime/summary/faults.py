"""Each scheduled fault of a run and what it did, for the summary's
``faults``: its ticks, the world's events for it, the counters the link
layer, the cameras and the wheels kept for it and, for a process fault,
what the launcher executed and how the robot came back; for one that
ends, how the formation came back.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from formation_swarm.runtime.summary.recovery import window_recoveries

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario


def fault_effects(
    sc: Scenario,
    parts: Mapping[str, Any],
    executed: list[dict[str, Any]] | None = None,
    link_faults: Mapping[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Each scheduled fault, its ticks and what it did: the events the world
    logged for it (``fault_log``: killed, started, readmitted, rejoined, frozen,
    thawed, lost ...); the counters kept for it: by the link layer under its
    index (``link_faults``), by the world's cameras and wheels under its string
    (``sensor_faults``, ``actuator_faults``, per robot); for process faults what the launcher
    executed (``executed``: its events for the fault, with wall times), each
    return of the robot (``rejoins``: ticks and wall seconds from the "start"
    call, or the loss, to the agent's first command) and how the formation
    came back (``recoveries``, world.recovery; for the other faults that end,
    from the error's 1 s windows: runtime.summary.recovery)."""
    world = parts.get("world", {})
    log = world.get("fault_log", []) or []
    launcher = [e for e in executed or [] if e.get("fault")]
    out = []
    for index, f in enumerate(sc.faults):
        text = str(f)
        counts: dict[str, int] = {k: v for k, v in ((link_faults or {}).get(str(index)) or {}).items() if k != "fault"}
        for group in ("sensor_faults", "actuator_faults"):  # the world's: {fault: {robot: {count: n}}}
            for rid, robot_counts in ((world.get(group) or {}).get(text) or {}).items():
                for key, value in (robot_counts or {}).items():
                    counts[f"R{rid} {key}"] = value
        out.append(
            {
                "index": index,
                "fault": text,
                "kind": f.kind,
                "group": f.group,
                "target": f.target,
                "at_s": f.at_s,
                "for_s": f.for_s,
                "start_tick": f.start_tick(sc.dt_s),
                "end_tick": _within(f.end_tick(sc.dt_s), sc.ticks),  # a fault lasting past the end: cut there
                "events": [e for e in log if e.get("fault") == text],
                "counts": counts,
            }
        )
        if f.process is not None:
            out[-1]["executed"] = [e for e in launcher if e.get("fault") == text]
            out[-1]["rejoins"] = [r for r in world.get("rejoins", []) or [] if r.get("fault") == text]
            out[-1]["recoveries"] = [r for r in world.get("recoveries", []) or [] if r.get("fault") == text]
        else:  # a fault that ends: the formation's return, from the error's 1 s windows
            out[-1]["recoveries"] = window_recoveries(f, sc, world.get("error_windows"))
    return out


def _within(end: int | None, ticks: int) -> int | None:
    return None if end is None else min(end, ticks)
