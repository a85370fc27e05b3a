"""A run's ``summary.json``: the one place that builds it, for ``swarm run``
(the launcher, from every process's stats) and for ``swarm world --out``
(the world alone, from its own).

Besides the metrics it says which code made the run and why the run ended:

``version``, ``git_commit``
    ``formation_swarm.__version__``, and the commit checked out in the source
    tree when the package runs from a git checkout (None otherwise).
``laws``
    the leader's policy and each follower's law by its id, named as
    ``spec.laws`` names them: ``{"leader": "path", "followers": {"2":
    "fuzzy (V_N dynamic)", "3": "pkg.module:Class"}}``.
``end_reason``, ``ended_at_s``, ``ended``
    one of ``END_REASONS`` and the sim time (s) the run had reached then,
    None when it never started; and the two in words (for a failed run, with
    the processes that exited on their own).
``links``, ``link_totals``, ``link_faults``
    every directed link's counts (received, dropped, partitioned, delayed,
    duplicated, reordered, held at the end), by link name; their sums per
    link class (``obs``, ``cmd``, ``formation``); and per link fault, by its
    index in the scenario's schedule, the fault and the messages it affected
    on all its links. ``partial_links``: the links into a robot whose agent a
    signal killed, whose counts are those of its last write of its stats.
``error_windows``
    per follower, its mean and largest formation error in each window
    (``window_s``, 1 s) of the run: how long a formation took to recover.
``controller_failures``
    every follower controller that raised or gave a speed that is no finite
    number: robot, tick, error, law (docs/controllers.md); any fails the run.
``step_times``, ``not_reproducible``, ``slow_controllers``, ``hung_controllers``
    each robot's step times; the robots whose lockstep misses no scheduled
    fault explains, the controllers slower than the tick in real time and
    those that hung (runtime.summary.slow); a robot not reproducible or hung
    fails the run.

Lists that grow with the run's length are capped, each cap stated
(``runtime.summary.caps``). Its parts are made beside it: why the run ended (``end_reason``), the links'
counts (``link_counts``), what each fault did (``fault_effects``) and what the
recording misses (``recording_check``).
"""

from __future__ import annotations

import contextlib
import json
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, NotRequired, TypedDict, Unpack

from formation_swarm.common.version import __version__
from formation_swarm.runtime.proc import write_json
from formation_swarm.runtime.summary import caps
from formation_swarm.runtime.summary.end_reason import (
    DURATION_REACHED,
    END_REASONS,
    INTERRUPTED,
    LEADER_FINISHED,
    PEERS_TIMEOUT,
    ROLE_FAILED,
    START_FAILED,
    TIMED_OUT,
    LostAgents,
    controller_failures,
    describe_controller_failures,
    describe_end,
    describe_host_lost,
    describe_waited,
    lost_agents,
    robots_lost,
    world_failed,
)
from formation_swarm.runtime.summary.faults import fault_effects
from formation_swarm.runtime.summary.links import killed_agents, link_sums, mark_partial_counts, partial_links
from formation_swarm.runtime.summary.recording import logger_lost, recording_cut, recording_gap
from formation_swarm.runtime.summary.slow import (
    describe_hung,
    describe_not_reproducible,
    hung_controllers,
    not_reproducible,
    slow_controllers,
    step_times,
)
from formation_swarm.spec.laws import laws

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

DUPLICATE_ANSWER = "duplicate answer"  # the reason of a robot's second answer to one tick, refused by the world

# What the launcher, the world, the report and the studies take from here.
__all__ = [
    "DUPLICATE_ANSWER",
    "DURATION_REACHED",
    "END_REASONS",
    "INTERRUPTED",
    "LEADER_FINISHED",
    "PEERS_TIMEOUT",
    "ROLE_FAILED",
    "START_FAILED",
    "TIMED_OUT",
    "Ending",
    "LostAgents",
    "build",
    "controller_failures",
    "describe_end",
    "describe_host_lost",
    "fault_effects",
    "git_commit",
    "logger_lost",
    "lost_agents",
    "partial_links",
    "read_parts",
    "recording_cut",
    "recording_gap",
    "rejections",
    "robots_lost",
    "run_failed",
    "world_failed",
    "write",
]


class Ending(TypedDict):
    """How a run ended, as :func:`build` takes it (by keyword)."""

    exit_code: int
    end_reason: str  # one of END_REASONS
    ended_at_s: float | None  # the sim time reached; None: the run never started
    interrupted: bool
    timed_out: bool
    limit_s: NotRequired[float | None]  # the wall-clock limit, said with TIMED_OUT


def build(
    *,
    run_id: str,
    sc: Scenario,
    mode: str,
    parts: Mapping[str, Any],
    processes: Mapping[str, Any],
    events: list[dict[str, Any]],
    recording: str | None,
    **ending: Unpack[Ending],
) -> dict[str, Any]:
    """The summary of one run from its processes' stats (``parts``: name -> stats;
    the world's is ``parts["world"]``, and holds most of the metrics)."""
    if ending["end_reason"] not in END_REASONS:
        raise ValueError(f"end_reason must be one of {END_REASONS}, got {ending['end_reason']!r}")
    world = parts.get("world", {})
    rejected = rejections(parts)
    links = _links(parts)
    link_totals, link_faults = link_sums(links, sc)
    out = {
        "run_id": run_id,
        "scenario": sc.name,
        "mode": mode,
        "seed": sc.seed,
        "laws": laws(sc),
        "version": __version__,
        "git_commit": git_commit(),
        **_ending(ending, parts, sc, events),
        **_controllers(parts, sc, events),
        **_world_metrics(world, sc),
        "faults": fault_effects(sc, parts, events, link_faults),
        "messages": world.get("messages", {}),
        "links": links,
        "partial_links": partial_links(processes, sc),
        "link_totals": link_totals,
        "link_faults": link_faults,
        "drops_total": sum(v.get("dropped", 0) for v in links.values()),
        "rejected": rejected,
        "rejected_total": sum(sum(r.values()) for r in rejected.values()),
        "trajectory_digest": world.get("trajectory_digest"),
        "robot_digests": world.get("robot_digests"),  # each robot's own, by id
        "events": events,
        "processes": dict(processes),
        "recording": recording,
        "parts": dict(parts),
    }
    mark_partial_counts(out["faults"], sc.faults, out["partial_links"], killed_agents(processes, parts, events))
    # Lockstep: what the recording misses of what was sent (None when whole).
    out["recording_gap"] = recording_gap(out)
    out["recording_cut"] = recording_cut(out)  # the logger was killed or lost before the run's end
    if out["failure"] is None:  # lost outside the schedule: the run has no whole recording
        out["failure"] = logger_lost(world, events)
    return caps.cap(out)  # a size independent of the run's length


def rejections(parts: Mapping[str, Any]) -> dict[str, dict[str, int]]:
    """What each process rejected, by reason (its stats' ``rejected``), and
    the world's answers refused as a robot's second for a tick it had
    answered (its ``duplicate_agents``: a second agent of the robot), as
    DUPLICATE_ANSWER."""
    out = {
        name: dict(part["rejected"])
        for name, part in parts.items()
        if isinstance(part, Mapping) and isinstance(part.get("rejected"), Mapping)
    }
    world_part = parts.get("world")
    duplicates = world_part.get("duplicate_agents") if isinstance(world_part, Mapping) else None
    counts = duplicates.values() if isinstance(duplicates, Mapping) else ()
    if n := sum(v for v in counts if isinstance(v, int) and not isinstance(v, bool)):
        world = out.setdefault("world", {})
        world[DUPLICATE_ANSWER] = world.get(DUPLICATE_ANSWER, 0) + n
    return {name: reasons for name, reasons in out.items() if reasons}


def _ending(ending: Ending, parts: Mapping[str, Any], sc: Scenario, events: list[dict[str, Any]]) -> dict[str, Any]:
    """The summary's fields of how the run ended, and why it failed if it did."""
    reason, at = ending["end_reason"], ending["ended_at_s"]
    world = parts.get("world", {})
    hosts_lost = [describe_host_lost(e) for e in events if e.get("event") == "host lost"]
    failure = "; ".join(hosts_lost) or robots_lost(world, sc)  # a lost host fails the run, its robots with it
    failure = "; ".join(w for w in (failure, *_controllers_failed(parts, sc, events)) if w) or None
    if reason == ROLE_FAILED:  # the world failed, or a process before tick 0: named first
        died = world_failed(events) or (None if failure else describe_end(reason, at, events))
        failure = "; ".join(w for w in (died, failure) if w) or None
    if reason == START_FAILED:
        failure = describe_end(reason, None, events)
    return {
        "exit_code": ending["exit_code"],
        "end_reason": reason,
        # The same in words; the world's own words for what it waited for in vain.
        "ended": (reason == PEERS_TIMEOUT and describe_waited(world))
        or describe_end(reason, at, events, ending.get("limit_s")),
        "failure": failure,
        "ended_at_s": at,
        "interrupted": ending["interrupted"],
        "timed_out": ending["timed_out"],
    }


def _controllers(parts: Mapping[str, Any], sc: Scenario, events: list[dict[str, Any]]) -> dict[str, Any]:
    """The controllers that failed, hung or were too slow, and each robot's step times."""
    world = parts.get("world", {})
    return {
        "controller_failures": controller_failures(parts),
        "step_times": step_times(parts),
        "not_reproducible": not_reproducible(world, parts, sc),
        "slow_controllers": slow_controllers(world, parts, sc),
        "hung_controllers": hung_controllers(parts, events, sc),
    }


def _controllers_failed(parts: Mapping[str, Any], sc: Scenario, events: Iterable[Mapping[str, Any]]) -> list[str]:
    """Why the controllers fail the run, in words: one raised, hung, or missed
    a lockstep deadline no scheduled fault explains (none: they do not)."""
    hung = hung_controllers(parts, events, sc)
    late = describe_not_reproducible(not_reproducible(parts.get("world", {}), parts, sc), (h["robot"] for h in hung))
    return [w for w in (describe_controller_failures(controller_failures(parts)), *describe_hung(hung), late) if w]


def run_failed(parts: Mapping[str, Any], sc: Scenario, events: Iterable[Mapping[str, Any]] = ()) -> str | None:
    """Why a run that ran to its end still failed (None: it did not): its
    leader or every follower lost its agent, or a controller failed, hung
    or missed a lockstep deadline no scheduled fault explains (``events``:
    the launcher's, which say the agents killed at the stop timeout)."""
    lost = robots_lost(parts.get("world", {}), sc)
    return "; ".join(w for w in (lost, *_controllers_failed(parts, sc, list(events))) if w) or None


def _world_metrics(world: Mapping[str, Any], sc: Scenario) -> dict[str, Any]:
    """The world's metrics of the run, as the summary gives them."""
    return {
        "ticks": world.get("ticks"),
        "sim_time_s": world.get("sim_time_s"),
        "ticks_per_s": world.get("ticks_per_s"),
        "followers": world.get("followers", {}),  # a follower that never saw its reference: "acquired": false
        "scenario_warnings": list(sc.warnings),
        "error_windows": world.get("error_windows"),
        "min_distance_m": world.get("min_distance_m"),
        "robot_diameter_m": world.get("robot_diameter_m"),
        "collisions": world.get("collisions"),
        "obstacle_collisions": world.get("obstacle_collisions"),
        "contacts": world.get("contacts", []),  # the first ones: tick, time_s, robots or robot and obstacle
        "lockstep_misses": world.get("lockstep_misses"),
        "late_ticks": world.get("late_ticks"),
        "max_tick_lateness_s": world.get("max_tick_lateness_s"),
        "p99_tick_lateness_s": world.get("p99_tick_lateness_s"),
        "world_scheduling": world.get("scheduling"),  # real time: the world's class (swarm.proc.realtime_priority)
        "stale_stops": world.get("stale_stops"),
        "formation_events": world.get("formation_events", []),
        "sensor_faults": world.get("sensor_faults", {}),
        "actuator_faults": world.get("actuator_faults", {}),
        "deaths": world.get("deaths", []),
        "stalls": world.get("stalls", []),  # lockstep: robots silent with their token there (world.stalls)
        "held_for_lost_s": world.get("held_for_lost_s"),
    }


def git_commit(root: Path | None = None) -> str | None:
    """The commit checked out at ``root`` (default: the folder holding the
    package's source, so an installed copy has none), read from ``.git``
    without running git; None when there is none or it cannot be read."""
    if root is None:
        root = Path(__file__).resolve().parents[3]
    with contextlib.suppress(OSError, ValueError, UnicodeDecodeError):
        git = root / ".git"
        if git.is_file():  # a worktree or submodule: "gitdir: PATH"
            git = (root / git.read_text().split("gitdir:", 1)[1].strip()).resolve()
        head = (git / "HEAD").read_text().strip()
        if not head.startswith("ref:"):
            return head if _is_sha(head) else None
        ref = head[4:].strip()
        common = git
        if (git / "commondir").is_file():  # a worktree keeps its refs in the main repository
            common = (git / (git / "commondir").read_text().strip()).resolve()
        for d in (git, common):
            if (d / ref).is_file():
                sha = (d / ref).read_text().strip()
                return sha if _is_sha(sha) else None
        packed = common / "packed-refs"
        if packed.is_file():
            for line in packed.read_text().splitlines():
                sha, _, name = line.partition(" ")
                if name.strip() == ref and _is_sha(sha):
                    return sha
    return None


def _is_sha(text: str) -> bool:
    return re.fullmatch(r"[0-9a-f]{40}|[0-9a-f]{64}", text) is not None


def read_parts(stats_dir: Path) -> dict[str, Any]:
    """Every process's stats file in ``stats_dir`` (``world.json``, ``agent-2.json`` ...)
    by process name; unreadable ones are left out."""
    parts: dict[str, Any] = {}
    for p in sorted(stats_dir.glob("*.json")):
        with contextlib.suppress(OSError, json.JSONDecodeError):
            parts[p.stem] = json.loads(p.read_text())
    return parts


def _links(parts: Mapping[str, Any]) -> dict[str, Any]:
    """Every link's counts: the world's command links and each agent's own;
    an agent restarted (agent-3.2 ...) adds its counts to the first's."""
    links: dict[str, Any] = dict(parts.get("world", {}).get("cmd_links", {}))
    for name, part in parts.items():
        if name.startswith("agent-"):
            for link, counts in (part.get("links") or {}).items():
                links[link] = _add(links.get(link, {}), counts)
    return links


def _add(a: Mapping[str, Any], b: Mapping[str, Any]) -> dict[str, Any]:
    """Counts added key by key, nested tables too (a link's per-fault counts)."""
    out = dict(a)
    for k, v in b.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = _add(out[k], v)
        elif isinstance(v, (int, float)) and not isinstance(v, bool) and isinstance(out.get(k), (int, float)):
            out[k] = out[k] + v
        else:
            out[k] = v
    return out


def write(run_dir: Path, summary: Mapping[str, Any]) -> Path:
    """``run_dir/summary.json``, written atomically; its path."""
    path = Path(run_dir) / "summary.json"
    write_json(str(path), dict(summary))
    return path
