"""A run's ``summary.json``: the one place that builds it, for ``swarm run``
(the launcher, from every process's stats) and for ``swarm world --out``
(the world alone, from its own).

Besides the metrics it says which code made the run and why the run ended:

``version``, ``git_commit``
    ``formation_swarm.__version__``, and the commit checked out in the source
    tree when the package runs from a git checkout (None otherwise).
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
"""

from __future__ import annotations

import contextlib
import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.common.faults import LINK, LINK_CLASSES, NETWORK
from formation_swarm.common.version import __version__
from formation_swarm.protocol.links import COUNTS_FINAL_AFTER_TICKS, EFFECTS, link_name
from formation_swarm.runtime.children import describe_exit
from formation_swarm.runtime.proc import write_json

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

LEADER_FINISHED = "leader_finished"  # the leader reached its last waypoint
DURATION_REACHED = "duration_reached"  # the scenario's duration_s ran out
INTERRUPTED = "interrupted"  # SIGINT or SIGTERM
TIMED_OUT = "timed_out"  # the wall-clock limit: swarm run --timeout, Launch.wait's, the fixture's timeout_s
PEERS_TIMEOUT = "peers_timeout"  # the world's peers did not appear within --peers-timeout
ROLE_FAILED = "role_failed"  # the world exited with an error (see "events" and "processes")
START_FAILED = "start_failed"  # the launcher could not start the run (a host missing, refusing, unfit)
END_REASONS = (LEADER_FINISHED, DURATION_REACHED, INTERRUPTED, TIMED_OUT, PEERS_TIMEOUT, ROLE_FAILED, START_FAILED)


def describe_end(
    reason: str | None,
    ended_at_s: float | None,
    events: list[Mapping[str, Any]] | None = None,
    limit_s: float | None = None,
) -> str:
    """``end_reason`` in words, for a report line; for a failed run, with the
    processes that exited on their own (from the launcher's ``events``)."""
    at = "" if ended_at_s is None else f" at t={ended_at_s:.2f} s"
    if reason == ROLE_FAILED:
        killed = {e.get("process") for e in events or [] if e.get("event") == "killed"}
        died = [
            f"{e.get('process')} {describe_exit(e['code'])}"
            for e in events or []
            if e.get("event") == "exited"
            and isinstance(e.get("code"), int)
            and e["code"] != 0
            and e.get("process") not in killed
        ]
        return f"a process failed{at}" + (f" ({'; '.join(died)})" if died else "")
    if reason == START_FAILED:
        why = [str(e.get("why")) for e in events or [] if e.get("event") == "start failed"]
        return "the run could not start" + (f": {why[0]}" if why else "")
    return {
        LEADER_FINISHED: f"the leader reached its last waypoint{at}",
        DURATION_REACHED: f"the scenario's duration was reached{at}",
        INTERRUPTED: f"stopped by a signal (Ctrl-C, SIGINT or SIGTERM){at}",
        TIMED_OUT: f"the wall-clock limit{f' of {limit_s:g} s' if limit_s else ''} was reached{at}",
        PEERS_TIMEOUT: "the peers did not appear in time",
    }.get(reason or "", f"unknown ({reason})")


def git_commit(root: Path | None = None) -> str | None:
    """The commit checked out at ``root`` (default: the folder holding the
    package's source, so an installed copy has none), read from ``.git``
    without running git; None when there is none or it cannot be read."""
    if root is None:
        root = Path(__file__).resolve().parents[2]
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


def describe_host_lost(ev: Mapping[str, Any]) -> str:
    """A "host lost" event of a run on hosts (its token went mid-run) as a sentence."""
    t = ev.get("sim_time_s")
    when = f"at sim t={t:.2f} s" if isinstance(t, (int, float)) and t >= 0 else "before the run started"
    robots = [str(r) for r in ev.get("robots") or []]
    dead = f"robot{'s' if len(robots) > 1 else ''} {', '.join(robots)} counted dead" if robots else "it ran no robot"
    return f"host {ev.get('host')} lost {when}: {dead}"


def robots_lost(world: Mapping[str, Any], sc: Scenario) -> str | None:
    """Why a run that ran to its end still failed: its leader lost its agent
    (the formation could not fly its path), or every follower did, for good
    (a robot whose agent came back, after a restart say, is not lost). None if not."""
    dead = world.get("dead_robots")  # at the end of the run; None in stats that do not say
    deaths = {d.get("robot"): d for d in world.get("deaths", []) if dead is None or d.get("robot") in dead}
    leader = sc.leader.robot_id
    if leader in deaths:
        return f"the leader (robot {leader}) lost its agent at t={deaths[leader].get('time_s', 0.0):.2f} s"
    if sc.follower_ids and all(rid in deaths for rid in sc.follower_ids):
        return f"every follower ({', '.join(map(str, sc.follower_ids))}) lost its agent"
    return None


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
    came back (``recoveries``, world.recovery)."""
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
    return out


def _within(end: int | None, ticks: int) -> int | None:
    return None if end is None else min(end, ticks)


def _links(parts: Mapping[str, Any]) -> dict[str, Any]:
    """Every link's counts: the world's command links and each agent's own;
    an agent restarted (agent-3.2 ...) adds its counts to the first's."""
    links: dict[str, Any] = dict(parts.get("world", {}).get("cmd_links", {}))
    for name, part in parts.items():
        if name.startswith("agent-"):
            for link, counts in (part.get("links") or {}).items():
                links[link] = _add(links.get(link, {}), counts)
    return links


def partial_links(processes: Mapping[str, Any], sc: Scenario) -> list[str]:
    """The links whose counts are partial: those into a robot one of whose agents
    (agent-3, agent-3.2, ...) a signal killed. Such an agent's counters are
    those of its last periodic write (up to its stats period of wall time old:
    nodes.agent_stats.STATS_PERIOD_S, longer beyond 25 robots),
    or none when it died before its first; how many messages it had by then
    depends on the machine's speed, not on the run."""
    killed = {rid for _, rid in _signalled_agents(processes)}
    leader = sc.leader.robot_id
    out = [link_name("obs", 0, r) for r in killed]
    out += [link_name("formation", leader, r) for r in killed if r != leader]
    return sorted(out)


def _killed_agents(
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
        if (rid := _robot_of(name)) is not None and isinstance(code, int) and code < 0:
            out.append((name, rid))
    return out


def _counts_cut(killed: list[tuple[int | None, int | None]], start: Any, end: Any) -> bool:
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


def recording_cut(summary: Mapping[str, Any]) -> str | None:
    """Where a fault killed the logger, what that did to the recording, in
    words (None: no such kill). By the fault's design, not a loss to retry
    (recording_gap): the recording ends there, minus what the logger had not
    yet written."""
    for e in summary.get("events") or []:
        if isinstance(e, Mapping) and e.get("event") == "killed" and e.get("process") == "logger":
            t = e.get("sim_time_s")
            when = f" at sim t={t:.2f} s" if isinstance(t, (int, float)) else ""
            fast = (
                "; a lockstep run passes many ticks in a second, so it may hold none"
                if summary.get("mode") == "lockstep"
                else ""
            )
            return (
                f"the logger was killed{when}: the recording ends before that, without what the logger had "
                f"not yet written (up to its last second of wall time{fast})"
            )
    return None


def recording_gap(summary: Mapping[str, Any]) -> str | None:
    """What a lockstep run's recording misses of what was sent (None: nothing,
    or nothing to tell: real time may drop by design, or no logger), with where
    the missing ticks are when the logger's stats say it. The recorded metrics
    (the measured and EKF target errors) come from the recording: a run that
    lost part of it gives wrong figures (swarm.sweep runs it again). Lockstep
    truth and telemetry are sent with Zenoh's BLOCK, yet in two of six test
    suites one fig9 run lost a batch (165 of 880 ticks of truth; 60 of 880
    telemetry messages), most likely at the run's end: processes left before
    a starved logger had taken what they sent (swarm.proc.wait_sent, the
    logger's END_WAIT_S and the world's LINGER_LOGGER_S now wait for it).

    Telemetry is compared robot by robot with what each follower answered,
    except for a robot whose agent a fault killed or restarted: the batch it
    held when killed dies with it, by the fault's design. A run stopped from
    outside (Ctrl-C, a timeout) loses what was in flight when its processes
    stopped: nothing to tell either (its summary says it was stopped)."""
    if summary.get("mode") != "lockstep" or summary.get("interrupted") or summary.get("timed_out"):
        return None
    parts = summary.get("parts") or {}
    logger = parts.get("logger") or {}
    taken = logger.get("messages") or {}
    ticks = logger.get("ticks") if isinstance(logger.get("ticks"), Mapping) else None
    sent_truth = (summary.get("messages") or {}).get("truth_sent")
    got = taken.get("truth")
    if isinstance(got, int) and isinstance(sent_truth, int) and got < sent_truth:
        where = _missing_ticks("truth", (ticks or {}).get("0"), sent_truth)
        return f"the logger recorded {got} of the {sent_truth} ticks the world sent" + (
            f" (missing: {where})" if where else ""
        )
    faulted = {
        _robot_of(e.get("process"))
        for e in summary.get("events") or []
        if isinstance(e, Mapping) and e.get("event") in ("killed", "started")
    }
    answered: dict[int, int] = {}
    for name, p in parts.items():
        rid = _robot_of(name)
        if (
            isinstance(p, Mapping)
            and p.get("role") == "follower"
            and rid is not None
            and isinstance(p.get("answered"), int)
        ):
            answered[rid] = answered.get(rid, 0) + p["answered"]
    if ticks is None:  # a logger's stats from before per-sender ticks: the totals
        total = taken.get("telemetry")
        if not faulted and answered and isinstance(total, int) and total < sum(answered.values()):
            return (
                f"the logger recorded {total} of the {sum(answered.values())} telemetry messages the followers "
                "sent (one per tick answered)"
            )
        return None
    for rid, sent in sorted(answered.items()):
        t = ticks.get(str(rid))
        if rid in faulted:
            continue
        if not isinstance(t, Mapping):  # none of its telemetry reached the logger
            if sent > 0:
                return f"the logger recorded none of the {sent} telemetry messages R{rid} sent (one per tick answered)"
            continue
        first, last, missing = t.get("first"), t.get("last"), t.get("missing", 0)
        if not (isinstance(first, int) and isinstance(last, int) and isinstance(missing, int)):
            continue
        if (got := last - first + 1 - missing) < sent:
            where = _missing_ticks(f"R{rid}'s telemetry", t, sent_truth)
            return f"the logger recorded {got} of the {sent} telemetry messages R{rid} sent (one per tick answered)" + (
                f" (missing: {where})" if where else ""
            )
    return None


def _robot_of(process: Any) -> int | None:
    """The robot of an agent's process name (agent-3, agent-3.1), else None."""
    if not isinstance(process, str) or not process.startswith("agent-"):
        return None
    head = process[len("agent-") :].split(".", 1)[0]
    return int(head) if head.isdigit() else None


def _missing_ticks(name: str, t: Any, n_ticks: Any) -> str:
    """From one sender's tick stats in the logger's (swarm.logger: first, last and
    the gaps between), which ticks of its stream (``name``) it never took, in words."""
    if not isinstance(t, Mapping) or not isinstance(n_ticks, int):
        return ""
    first, last = t.get("first"), t.get("last")
    if not isinstance(first, int) or not isinstance(last, int):
        return ""
    runs = [g for g in t.get("gaps") or [] if isinstance(g, list) and len(g) == 2]
    runs = ([[0, first - 1]] if first > 0 else []) + runs + ([[last + 1, n_ticks - 1]] if last < n_ticks - 1 else [])
    return f"{name} ticks " + ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs) if runs else ""


def build(
    *,
    run_id: str,
    sc: Scenario,
    mode: str,
    parts: Mapping[str, Any],
    exit_code: int,
    end_reason: str,
    ended_at_s: float | None,
    interrupted: bool,
    timed_out: bool,
    limit_s: float | None = None,
    processes: Mapping[str, Any],
    events: list[dict[str, Any]],
    recording: str | None,
) -> dict[str, Any]:
    """The summary of one run from its processes' stats (``parts``: name -> stats;
    the world's is ``parts["world"]``, and holds most of the metrics)."""
    if end_reason not in END_REASONS:
        raise ValueError(f"end_reason must be one of {END_REASONS}, got {end_reason!r}")
    world = parts.get("world", {})
    hosts_lost = [describe_host_lost(e) for e in events if e.get("event") == "host lost"]
    failure = "; ".join(hosts_lost) or robots_lost(world, sc)  # a lost host fails the run, its robots with it
    if end_reason == START_FAILED:
        failure = describe_end(end_reason, None, events)
    rejected = {name: part.get("rejected", {}) for name, part in parts.items() if part.get("rejected")}
    links = _links(parts)
    link_totals, link_faults = _link_sums(links, sc)
    out = {
        "run_id": run_id,
        "scenario": sc.name,
        "mode": mode,
        "seed": sc.seed,
        "version": __version__,
        "git_commit": git_commit(),
        "exit_code": exit_code,
        "end_reason": end_reason,
        "ended": describe_end(end_reason, ended_at_s, events, limit_s),  # the same in words
        "failure": failure,
        "ended_at_s": ended_at_s,
        "interrupted": interrupted,
        "timed_out": timed_out,
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
        "events": events,
        "processes": dict(processes),
        "recording": recording,
        "parts": dict(parts),
    }
    # Counts kept by an agent a signal killed are a lower bound, unless it wrote
    # them after the fault's window had ended (it does, COUNTS_FINAL_AFTER_TICKS later).
    killed = _killed_agents(processes, parts, events)
    for f, fault in zip(out["faults"], sc.faults, strict=True):
        cut = sorted(
            {
                int(name.split(">")[1])
                for name in out["partial_links"]
                if fault.group in (LINK, NETWORK)
                and name.split(":")[0] in (fault.link_classes or LINK_CLASSES)
                and fault.applies_to(int(name.split(">")[1]))
            }
        )
        cut = [r for r in cut if _counts_cut(killed.get(r, []), f.get("start_tick"), f.get("end_tick"))]
        if cut:
            f["counts_partial_for"] = cut  # the robots whose agent's counts end at its last stats write
    # Lockstep: what the recording misses of what was sent (None when whole).
    out["recording_gap"] = recording_gap(out)
    out["recording_cut"] = recording_cut(out)  # a fault killed the logger
    return out


def _link_sums(links: Mapping[str, Any], sc: Scenario) -> tuple[dict[str, Any], dict[str, Any]]:
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


def write(run_dir: Path, summary: Mapping[str, Any]) -> Path:
    """``run_dir/summary.json``, written atomically; its path."""
    path = Path(run_dir) / "summary.json"
    write_json(str(path), dict(summary))
    return path
