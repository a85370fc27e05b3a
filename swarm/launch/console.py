"""What ``swarm run`` prints at the end of a run: its metrics and its events.

A run that ended early (no ticks, no metrics) prints what it has; a value
the run did not produce prints as "-", never an error.
"""

from __future__ import annotations

import shutil
import statistics
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from formation_swarm.launch import ros2 as ros2_mod
from formation_swarm.launch.words import (
    describe_counts,
    describe_event,
    describe_fault,
    describe_laws,
    describe_recoveries,
    describe_stall,
)
from formation_swarm.launch.words import num as _num
from formation_swarm.nodes.logger import viewer
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.summary.slow import describe_slow
from formation_swarm.spec import scenario as scenario_mod

if TYPE_CHECKING:
    from formation_swarm.launch.launcher import RunResult
    from formation_swarm.protocol.messages import Status

# The run's words (launch.words), taken from here too by the report and tests.
__all__ = [
    "contacts_line",
    "describe_counts",
    "describe_event",
    "describe_fault",
    "describe_laws",
    "describe_recoveries",
    "describe_stall",
    "losses",
    "print_result",
    "rejected_why",
]


# Up to this many followers each gets its own line; beyond, a line of their
# spread, the worst WORST_LISTED, and every one that lost its reference or was killed.
LIST_FOLLOWERS_UP_TO = 10
WORST_LISTED = 5
LOST_SIGHT_SHARE = 0.95  # beyond 10 followers, one whose reference was in fewer of its frames is listed


def rejected_why(s: Mapping[str, Any]) -> str:
    """The receivers' reasons for what they rejected, summed over them, as
    " (replayed or reordered 2)"; "" when none."""
    why: dict[str, int] = {}
    for reasons in (s.get("rejected") or {}).values():
        for reason, n in (reasons or {}).items() if isinstance(reasons, Mapping) else ():
            if isinstance(n, int):
                why[reason] = why.get(reason, 0) + n
    return f" ({', '.join(f'{r} {n}' for r, n in sorted(why.items(), key=lambda kv: -kv[1]))})" if why else ""


def losses(s: Mapping[str, Any]) -> str:
    """The messages the links lost: dropped (the links' drop probability, drop
    and burst faults) and, if any, lost to partitions."""
    cut = sum(t.get("partitioned", 0) for t in (s.get("link_totals") or {}).values() if isinstance(t, Mapping))
    dropped = s.get("drops_total")
    return f"messages dropped {dropped if isinstance(dropped, int) else '-'}" + (
        f", lost to partitions {cut}" if cut else ""
    )


def _follower_line(rid: str, m: Mapping[str, Any], kills: Mapping[str, tuple[Any, ...]]) -> str:
    if m.get("acquired") is False:
        return f"  follower R{rid}: NEVER ACQUIRED its reference (never in its camera's view): no metrics\n"
    seen, frames = m.get("seen_ticks"), m.get("frames")
    sight = ""
    if isinstance(seen, int) and isinstance(frames, int) and seen < frames:
        sight = f" (its reference in view in {seen} of {frames} camera frames)"
    whole = f"RMS {_num(m.get('rms_m'))} m, max {_num(m.get('max_m'))} m"
    if f"agent-{rid}" not in kills:
        return f"  follower R{rid}: formation error {whole}{sight}\n"
    killed_at, restarted_at, *how = kills[f"agent-{rid}"]
    back = f", a fresh one started at t={_num(restarted_at, '.2f')} s" if restarted_at is not None else ""
    killed = f"its agent was {(how or ['killed'])[0]} at t={_num(killed_at, '.2f')} s{back}"
    before = m.get("until_stopped")
    if not isinstance(before, Mapping):  # a summary from before until_stopped
        return f"  follower R{rid}: formation error {whole} ({killed}; these include the robot after that){sight}\n"
    return (
        f"  follower R{rid}: formation error RMS {_num(before.get('rms_m'))} m, max "
        f"{_num(before.get('max_m'))} m until {killed}; over the whole run, the robot after that "
        f"included: {whole}{sight}\n"
    )


def _lost_sight(m: Mapping[str, Any]) -> bool:
    """Never saw its reference, or not in LOST_SIGHT_SHARE of its camera frames."""
    seen, frames = m.get("seen_ticks"), m.get("frames")
    lost = isinstance(seen, int) and isinstance(frames, int) and seen < LOST_SIGHT_SHARE * frames
    return m.get("acquired") is False or lost


def _many_followers(
    w: Any, followers: list[tuple[str, Mapping[str, Any]]], kills: Mapping[str, tuple[Any, ...]]
) -> list[tuple[str, Mapping[str, Any]]]:
    """Write the spread of the followers' errors; return the followers to list
    one by one: the worst by RMS, then any other that lost sight of its
    reference (never saw it, or not in LOST_SIGHT_SHARE of its frames) or
    was killed."""
    measured = [(rid, m) for rid, m in followers if isinstance(m.get("rms_m"), (int, float))]
    rms = sorted(float(m["rms_m"]) for _, m in measured)
    if rms:
        worst = max(measured, key=lambda kv: float(kv[1]["rms_m"]))[0]
        maxes = [(float(m["max_m"]), rid) for rid, m in measured if isinstance(m.get("max_m"), (int, float))]
        largest = f", largest error {_num(max(maxes)[0])} m (R{max(maxes)[1]})" if maxes else ""
        w(
            f"  {len(followers)} followers: formation error RMS median {_num(statistics.median(rms))} m, "
            f"best {_num(rms[0])} m, worst {_num(rms[-1])} m (R{worst}){largest}\n"
        )
    else:
        w(f"  {len(followers)} followers: no formation error measured\n")
    by_rms = sorted(measured, key=lambda kv: -float(kv[1]["rms_m"]))[:WORST_LISTED]
    shown = {rid for rid, _ in by_rms}
    flagged = [(rid, m) for rid, m in followers if rid not in shown and (_lost_sight(m) or f"agent-{rid}" in kills)]
    also = f", then {len(flagged)} more that lost sight of their reference or were killed" if flagged else ""
    if by_rms or flagged:
        every = f'(all {len(followers)}: summary.json, "followers")'
        w(f"  the {len(by_rms)} worst by RMS over the whole run{also} {every}:\n")
    return by_rms + flagged


def _skipped(parts: Any) -> str:
    """Real time: the share of the followers' observations they never answered
    (a newer one had come by the time they got to it)."""
    followers = [p for p in (parts or {}).values() if isinstance(p, Mapping) and p.get("role") == "follower"]
    counts = [(p.get("answered"), p.get("superseded")) for p in followers]
    answered = sum(a for a, _ in counts if isinstance(a, int))
    skipped = sum(k for _, k in counts if isinstance(k, int))
    if answered + skipped == 0:
        return ""
    return f", followers skipped {100.0 * skipped / (answered + skipped):.1f}% of their observations"


CONTACTS_SHOWN = 3


def contacts_line(contacts: list[Any], collisions: Any, obstacle_collisions: Any) -> str:
    """The first contacts, who and when: "first contacts: R4 and R5 at 12.35 s,
    R7 and obstacle 0 at 20.10 s (all 9 in summary.json, "contacts")"."""
    said = []
    for c in contacts[:CONTACTS_SHOWN]:
        if not isinstance(c, Mapping):
            continue
        robots = c.get("robots")
        if isinstance(robots, list) and len(robots) == 2:
            who = f"R{robots[0]} and R{robots[1]}"
        else:
            who = f"R{c.get('robot')} and obstacle {c.get('obstacle')}"
        said.append(f"{who} at {_num(c.get('time_s'), '.2f')} s")
    if not said:
        return ""
    counted = sum(n for n in (collisions, obstacle_collisions) if isinstance(n, int))
    rest = ""
    if counted > len(said):  # the world lists the first ones only (world.engine.CONTACTS_LISTED)
        which = f"all {counted}" if len(contacts) >= counted else f"the first {len(contacts)} of {counted}"
        rest = f' ({which} in summary.json, "contacts")'

    return f"first contact{'s' if len(said) > 1 else ''}: {', '.join(said)}{rest}"


def _changes(events: list[Any], grouped: bool) -> str:
    """The formation events, one by one; ``grouped``: those of one formation
    at one time together ("line at 5.00 s: robots 2-30")."""
    events = [e for e in events if isinstance(e, Mapping)]
    if not grouped:
        return ", ".join(f"R{e.get('robot')} {e.get('formation')} at {_num(e.get('time_s'), '.2f')} s" for e in events)
    groups: dict[tuple[Any, Any], list[Any]] = {}
    for e in events:
        groups.setdefault((e.get("formation"), e.get("time_s")), []).append(e.get("robot"))
    out = []
    for (formation, time_s), rids in groups.items():
        ints = all(isinstance(r, int) and not isinstance(r, bool) for r in rids)
        if len(rids) == 1 or not ints:
            who = ", ".join(f"R{r}" for r in rids)
        else:
            who = f"robots {scenario_mod.id_ranges(rids)}"
        out.append(f"{formation} at {_num(time_s, '.2f')} s: {who}")
    return "; ".join(out)


def print_result(res: RunResult, out: TextIO = sys.stdout) -> None:
    """The run's metrics on the console; a run that ended early has fewer (never an error)."""
    s = res.summary
    w = out.write
    ticks = s.get("ticks")
    w(
        f"run {s.get('run_id')}: exit {res.exit_code}, {ticks if ticks is not None else 'no'} ticks, "
        f"sim {_num(s.get('sim_time_s'), '.2f')} s\n"
    )
    w(f"  ended: {s.get('ended') or summary_mod.describe_end(s.get('end_reason'), s.get('ended_at_s'))}\n")
    if s.get("failure"):
        w(f"  failed: {s['failure']}\n")
    seen = s.get("ticks_seen")  # the launcher's last status: the run had ticked, whatever the world wrote
    if not ticks and isinstance(seen, int):
        w(f"  no metrics: the world wrote none (the run had reached tick {seen})\n")
    elif not ticks:
        w("  no metrics: the run ended before its first tick\n")
    else:
        _metrics(w, s)
    _faults_and_events(w, s)
    if isinstance(ros2 := s.get("ros2"), Mapping):
        w(f"  {ros2_mod.result_line(ros2)}\n")
    if s.get("unkept"):
        w(f"run folder: {res.run_dir}: nothing of the run is kept there ({s['unkept']})\n")
        return
    w(f"run folder: {res.run_dir}\n  summary: {res.run_dir / 'summary.json'}\n")
    if s.get("recording") and res.recording.is_file():
        if not ticks and not isinstance(seen, int):  # stopped before its first tick: the file holds nothing to watch
            w(f"  recording: {res.recording} (empty: the run ended before its first tick)\n")
        else:
            viewer = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
            cut = " (cut short: see above)" if s.get("recording_cut") else ""
            w(f"  recording: {res.recording}{cut}\n  open it:   {viewer} {res.recording}\n")
    if (wire := res.run_dir / "wire.mcap").is_file():  # every message, for swarm replay and Foxglove
        w(f"  messages:  {wire} (swarm replay {res.run_dir} --robot N)\n")


def _kills(s: Mapping[str, Any]) -> dict[str, tuple[Any, ...]]:
    """agent-N -> the sim times of its first kill and of its restart (None:
    none), or of its loss and "lost" for one lost otherwise (a crash, its host gone)."""
    kills: dict[str, tuple[Any, ...]] = {}
    for ev in s.get("events") or []:
        if isinstance(ev, Mapping) and ev.get("event") == "killed":
            kills.setdefault(str(ev.get("process")).split(".")[0], (ev.get("sim_time_s"), None))
        elif isinstance(ev, Mapping) and ev.get("event") == "started":  # a fresh agent: agent-N.2
            name = str(ev.get("process")).split(".")[0]
            if name in kills and kills[name][1] is None:
                kills[name] = (kills[name][0], ev.get("sim_time_s"))
    for d in s.get("deaths") or []:  # lost otherwise (a crash, its host gone): its error until then too
        if isinstance(d, Mapping) and f"agent-{d.get('robot')}" not in kills:
            kills[f"agent-{d.get('robot')}"] = (d.get("time_s"), None, "lost")
    return kills


def _metrics(w: Any, s: Mapping[str, Any]) -> None:
    """The metrics of a run that had ticks: the followers' errors, distances, formation changes, losses."""
    followers = sorted((s.get("followers") or {}).items(), key=lambda kv: (len(str(kv[0])), str(kv[0])))
    kills = _kills(s)
    listed = followers  # JSON keys: robot ids as text, listed by number
    if len(followers) > LIST_FOLLOWERS_UP_TO:
        listed = _many_followers(w, followers, kills)
    for rid, m in listed:
        w(_follower_line(rid, m, kills))
    w(
        f"  min distance {_num(s.get('min_distance_m'))} m (diameter {_num(s.get('robot_diameter_m'), 'g')} m), "
        f"collisions {s.get('collisions')}, obstacle collisions {s.get('obstacle_collisions')}\n"
    )
    if contacts := contacts_line(s.get("contacts") or [], s.get("collisions"), s.get("obstacle_collisions")):
        w(f"  {contacts}\n")
    changes = _changes(s.get("formation_events") or [], grouped=len(followers) > LIST_FOLLOWERS_UP_TO)
    w(f"  formation changes: {changes or 'none'}\n")
    if s.get("mode") == "realtime":
        late_ms = _num(1e3 * s["max_tick_lateness_s"] if s.get("max_tick_lateness_s") is not None else None, ".1f")
        sched = s.get("world_scheduling") or ""
        # A world the machine kept out of the real-time class: its ticks may start late under load.
        note = f" (world scheduling {sched})" if sched.startswith("normal (") else ""
        w(f"  late ticks {s.get('late_ticks')} (worst {late_ms} ms){note}{_skipped(s.get('parts'))}, {losses(s)}, ")
    else:
        w(f"  lockstep misses {s.get('lockstep_misses')}, {losses(s)}, ")
    w(f"rejected {s.get('rejected_total')}{rejected_why(s)}\n")
    for slow in s.get("slow_controllers") or []:  # real time: steps longer than the tick
        if isinstance(slow, Mapping):
            w(f"  slow controller: {describe_slow(slow)}\n")
    if s.get("recording_gap"):
        w(f"  RECORDING INCOMPLETE: {s['recording_gap']}\n")
    if s.get("recording_cut"):
        w(f"  RECORDING CUT SHORT: {s['recording_cut']}\n")


def _start_tick(f: Mapping[str, Any]) -> float:
    start = f.get("start_tick")
    return float(start) if isinstance(start, (int, float)) else float("inf")


def _start_tick(f: Mapping[str, Any]) -> float:
    start = f.get("start_tick")
    return float(start) if isinstance(start, (int, float)) else float("inf")


def _faults_and_events(w: Any, s: Mapping[str, Any]) -> None:
    """Each fault with what it did, by its start, then the robots that fell
    silent, then the events no fault's line said."""
    faults = [f for f in s.get("faults") or [] if isinstance(f, Mapping)]
    for f in sorted(faults, key=_start_tick):
        w(f"  fault: {describe_fault(f, s.get('ticks'))}\n")
    for e in s.get("stalls") or []:
        if isinstance(e, Mapping):
            w(f"  stall: {describe_stall(e)}\n")
    events = s.get("events") or []
    killed = {ev.get("process") for ev in events if ev.get("event") == "killed"}
    hung = {h.get("process") for h in s.get("hung_controllers") or [] if isinstance(h, Mapping)}
    for ev in events:
        if ev.get("fault") or ev.get("process") in hung:
            continue  # carried out for a fault, or a hung controller's: the lines above say it
        if not (ev.get("event") == "exited" and ev.get("process") in killed):  # the kill said it
            w(f"  event: {describe_event(ev)}\n")


def progress_line(st: Status) -> str:
    """A status's tick, share of the run and sim time."""
    pct = 100.0 * st.tick / max(1, st.total_ticks)
    return f"[swarm] tick {st.tick}/{st.total_ticks} ({pct:.0f}%), sim {st.time_s:.1f} s"


def reachable_live(live: str | None, say: Callable[[str], None]) -> str | None:
    """The viewer the logger also streams to: ``live`` if one answers there.
    Said here, once, when none does: the logger's own line would end in its log."""
    if live and (why := viewer.unreachable(live)) is not None:
        say(
            f"[swarm] --live {live}: no Rerun viewer answers there ({why}); not streaming "
            "there, the run is recorded to recording.rrd only"
        )
        return None
    return live
