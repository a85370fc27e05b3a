"""The counts of a run's links, as its summary gives them: their sums per
link class and per link fault, and which of them are partial because a
signal killed the agent that kept them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from formation_swarm.common.faults import LINK, LINK_CLASSES, NETWORK, Fault
from formation_swarm.protocol.links import COUNTS_FINAL_AFTER_TICKS, EFFECTS, link_name

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario


def link_sums(links: Mapping[str, Any], sc: Scenario) -> tuple[dict[str, Any], dict[str, Any]]:
    """Per link class (the name's part before ":") the sums of every count; per
    fault index the fault and the sums of its counts over its links."""
    totals: dict[str, dict[str, int]] = {}
    by_fault: dict[str, dict[str, Any]] = {}
    for name, counts in sorted(links.items()):
        total = totals.setdefault(name.split(":")[0], dict.fromkeys(("received", *EFFECTS, "held"), 0))
        for key in total:
            total[key] += int(counts.get(key, 0))
        for index, effects in counts.get("faults", {}).items():
            i = int(index)
            entry = by_fault.setdefault(index, {"fault": str(sc.faults[i]) if 0 <= i < len(sc.faults) else None})
            for effect, n in effects.items():
                entry[effect] = entry.get(effect, 0) + int(n)
    return totals, dict(sorted(by_fault.items(), key=lambda kv: int(kv[0])))


def partial_links(processes: Mapping[str, Any], sc: Scenario) -> list[str]:
    """The links whose counts are partial: those into a robot one of whose agents
    (agent-3, agent-3.2, ...) a signal killed. Such an agent's counters are
    those of its last periodic write (up to its stats period of wall time old:
    nodes.agent.stats.STATS_PERIOD_S, longer beyond 25 robots),
    or none when it died before its first; how many messages it had by then
    depends on the machine's speed, not on the run."""
    killed = {rid for _, rid in _signalled_agents(processes)}
    leader = sc.leader.robot_id
    out = [link_name("obs", 0, r) for r in killed]
    out += [link_name("formation", leader, r) for r in killed if r != leader]
    return sorted(out)


def killed_agents(
    processes: Mapping[str, Any], parts: Mapping[str, Any], events: list[dict[str, Any]]
) -> dict[int, list[tuple[int | None, int | None]]]:
    """Per robot, for each of its agents a signal killed: the tick its counts
    were last written at (its stats' ``last_tick``; None: no stats, or none
    answered) and the tick it was killed at (None: unknown)."""
    at: dict[str, int] = {}
    for e in events:
        if e.get("event") in ("killed", "exited") and _int(e.get("tick")) is not None:
            at.setdefault(str(e.get("process")), e["tick"])
    out: dict[int, list[tuple[int | None, int | None]]] = {}
    for name, rid in _signalled_agents(processes):
        out.setdefault(rid, []).append((_int((parts.get(name) or {}).get("last_tick")), at.get(name)))
    return out


def _signalled_agents(processes: Mapping[str, Any]) -> list[tuple[str, int]]:
    """The agents' processes (agent-3, agent-3.2) a signal killed, with their robot."""
    out = []
    for name, proc in processes.items():
        code = (proc or {}).get("exit_code")
        if (rid := robot_of(name)) is not None and isinstance(code, int) and code < 0:
            out.append((name, rid))
    return out


def counts_cut(killed: list[tuple[int | None, int | None]], start: Any, end: Any) -> bool:
    """Whether the robot's killed agents leave a fault's counts partial: one
    killed after the fault's start that last wrote them before they were final
    (COUNTS_FINAL_AFTER_TICKS after its end; a fault to the run's end never is)."""
    for written, died in killed:
        if isinstance(start, int) and died is not None and died <= start:
            continue  # gone before the fault began: it counted none of it
        if not isinstance(end, int) or written is None or written < end + COUNTS_FINAL_AFTER_TICKS:
            return True
    return False


def _int(x: Any) -> int | None:
    return x if isinstance(x, int) and not isinstance(x, bool) else None


def robot_of(process: Any) -> int | None:
    """The robot of an agent's process name (agent-3, agent-3.1), else None."""
    if not isinstance(process, str) or not process.startswith("agent-"):
        return None
    head = process[len("agent-") :].split(".", 1)[0]
    return int(head) if head.isdigit() else None


def mark_partial_counts(
    effects: list[dict[str, Any]],
    faults: tuple[Fault, ...],
    partial: list[str],
    killed: Mapping[int, list[tuple[int | None, int | None]]],
) -> None:
    """Mark in each fault's effects (fault_effects) the robots whose counts for
    it are partial: counts kept by an agent a signal killed are a lower bound,
    unless it wrote them after the fault's window had ended (it does,
    COUNTS_FINAL_AFTER_TICKS later)."""
    for f, fault in zip(effects, faults, strict=True):
        cut = sorted(
            {
                int(name.split(">")[1])
                for name in partial
                if fault.group in (LINK, NETWORK)
                and name.split(":")[0] in (fault.link_classes or LINK_CLASSES)
                and fault.applies_to(int(name.split(">")[1]))
            }
        )
        cut = [r for r in cut if counts_cut(killed.get(r, []), f.get("start_tick"), f.get("end_tick"))]
        if cut:
            f["counts_partial_for"] = cut  # the robots whose agent's counts end at its last stats write
