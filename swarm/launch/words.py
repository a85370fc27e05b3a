"""What a run's summary says, in words: the laws it flew, its events, each
fault and what it did, how the formation came back, the robots that fell
silent. The console (launch.console) and the report (report.faults) print these."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.children import KILLED_AT_STOP_TIMEOUT, describe_exit
from formation_swarm.spec.laws import LEADER_POLICY
from formation_swarm.world.recovery import HOLD_S


def num(value: Any, fmt: str = ".3f") -> str:
    """A number for the console, or "-" for a metric the run did not produce."""
    return format(value, fmt) if isinstance(value, (int, float)) and not isinstance(value, bool) else "-"


def describe_robots(n: int, per_process: int) -> str:
    """A run's robots, as its first line says them: "3 robots"; with K robots'
    agents a process, "100 robots, 10 a process (--agents-per-process)"."""
    said = f"{n} robot{'s' if n != 1 else ''}"
    return said + (f", {per_process} a process (--agents-per-process)" if per_process > 1 else "")


def describe_laws(laws: Mapping[str, Any]) -> str:
    """The leader's policy and the followers' laws (spec.laws) in a phrase:
    "leader path, law fuzzy (V_N dynamic)" when every follower flies one law,
    else each law with its followers, "leader path, laws R2,R3 lpsi; R4 pkg.mod:Ctl";
    "leader pkg.mod:Policy, ..." for a policy of the user's (a record without
    the leader's is from before policies could be named: "path")."""
    by_law: dict[str, list[int]] = {}
    for rid, law in (laws.get("followers") or {}).items():
        if str(rid).isdigit():
            by_law.setdefault(str(law), []).append(int(rid))
    leader = f"leader {laws.get('leader') or LEADER_POLICY}"
    if len(by_law) <= 1:
        return leader + "".join(f", law {law}" for law in by_law)
    groups = sorted(by_law.items(), key=lambda kv: min(kv[1]))
    return f"{leader}, laws " + "; ".join(f"{robot_ids(ids)} {law}" for law, ids in groups)


def robot_ids(ids: list[int]) -> str:
    """Robot ids in short, three or more consecutive ones as a range: "R2-R4,R7,R8"."""
    runs: list[list[int]] = []
    for rid in sorted(ids):
        if runs and rid == runs[-1][-1] + 1:
            runs[-1].append(rid)
        else:
            runs.append([rid])
    return ",".join(f"R{r[0]}-R{r[-1]}" if len(r) > 2 else ",".join(f"R{x}" for x in r) for r in runs)


def describe_event(ev: Mapping[str, Any]) -> str:
    """One event of the run (a kill, a process that exited, ...) as a sentence."""
    t = ev.get("sim_time_s")
    when = f"at sim t={t:.2f} s" if isinstance(t, (int, float)) and t >= 0 else "before the run started"
    if ev.get("event") in ("killed", "started", "frozen", "thawed"):
        tick = f" (tick {ev['tick']})" if isinstance(ev.get("tick"), int) else ""
        why = f"'{ev['fault']}'" if ev.get("fault") else "fault injection"
        return f"{ev['event']} {ev.get('process')} {when}{tick} ({why})"
    if (said := _describe_host_event(ev) or _describe_login_event(ev, when)) is not None:
        return said
    if ev.get("event") == "exited" and ev.get("host_lost"):  # its exit code stayed on that host
        return f"{ev.get('process')} lost with host {ev['host_lost']} {when}"
    if ev.get("event") == "not fetched":  # a remote agent's log and stats, at the run's end
        return f"{ev.get('process')}'s log and stats were not fetched: {ev.get('why')}"
    if ev.get("event") == KILLED_AT_STOP_TIMEOUT:
        return f"{ev.get('process')} did not leave within the stop timeout: killed (SIGKILL)"
    if ev.get("event") == "exit code not reported by the fork server":
        return f"{ev.get('process')}'s exit code {ev.get('code')} is its own record: the fork server did not report it"
    if ev.get("event") == "exited" and isinstance(ev.get("code"), int):
        tick = f" (tick {ev['tick']})" if isinstance(ev.get("tick"), int) else ""
        return f"{ev.get('process')} {describe_exit(ev['code'])} {when}{tick}"
    return ", ".join(f"{k} {v}" for k, v in ev.items() if k != "log_tail")


def _describe_login_event(ev: Mapping[str, Any], when: str) -> str | None:
    """An outside agent's coming and going, a robot's login used twice, as a sentence; None for any other event."""
    robot = ev.get("robot")
    if ev.get("event") in ("outside agent connected", "outside agent left"):  # launch.external's
        return f"robot {robot}'s {ev['event']} {when}"
    if ev.get("event") == "robot login used twice":  # launch.logins'
        if ev.get("kept_token"):
            return f"robot {robot}'s login ({ev.get('login')}) used by a second session, which kept its token {when}"
        refused = ev.get("answers_refused")
        return f"robot {robot}'s login ({ev.get('login')}) used by a second session: {refused} answers refused"
    return None


def _describe_host_event(ev: Mapping[str, Any]) -> str | None:
    """An event of a run's hosts as a sentence; None for any other event."""
    if ev.get("event") == "host lost":
        return summary_mod.describe_host_lost(ev)
    if ev.get("event") == "host left out":  # its login answered from two sessions at the start
        return f"host {ev.get('host')} left out of the run: its login answered from two sessions"
    if ev.get("event") == "host login used twice":
        return (
            f"host {ev.get('host')}'s login answered from another session too: "
            f"{ev.get('answers_refused')} answers refused"
        )
    return None


def describe_recoveries(f: Mapping[str, Any]) -> list[str]:
    """How the formation came back after a fault, in words: when the watched
    follower's error first went below the bound after the robot's return,
    whether it then stayed below it for the hold time (settled), and its
    largest error in the window after the return. Below the bound at once but
    never settled is a follower whose error only passed through it. After a
    fault that ends (a link, partition, sensor or actuator fault), the same
    from the end, to the second (runtime.summary.recovery)."""
    out = []
    for rec in f.get("recoveries") or []:
        who = ", ".join(f"R{r}" for r in rec.get("watched") or [])
        since = rec.get("since_s")
        windowed = isinstance(rec.get("resolution_s"), (int, float))  # a fault's end, from 1 s windows
        what = " the fault's end" if windowed else " the return"
        at = f"{what} at t={since:.2f} s" if isinstance(since, (int, float)) else what
        after = rec.get("first_below_after_s")
        bound = rec.get("bound_m", 0.5)
        below = f"below {bound:g} m" + (f" ({rec['resolution_s']:g} s mean)" if windowed else "")
        if not isinstance(after, (int, float)):
            out.append(f"{who} not back {below} by the end")
            continue
        said = f"{who} {below} {'within ' if windowed else ''}{after:.2f} s after{at}"
        settled = rec.get("settled_after_s")
        if isinstance(settled, (int, float)):
            said += f", settled (below it for {HOLD_S:g} s) {settled:.2f} s after"
        elif not windowed:  # a window's mean below the bound is a second below it on average: no settling said
            said += f", never settled (below it for {HOLD_S:g} s in a row) by the end"
        if isinstance(peak := rec.get("max_in_window_m"), (int, float)):
            said += f"; largest error in the {rec.get('window_s', 5):g} s after: {peak:.2f} m"
        out.append(said)
    return out


# A fault's counts in words: what a link did to its messages, and what a
# camera or wheel fault did on each robot (summary.json keeps the raw keys).
LINK_EFFECT_WORDS = {
    "dropped": "dropped",
    "partitioned": "lost to the partition",
    "delayed": "delayed",
    "duplicated": "duplicated",
    "reordered": "reordered",
}
ROBOT_EFFECT_WORDS = {
    "blacked_out": "readings blacked out",
    "cut": "readings cut by the range",
    "replaced": "readings replaced by outliers",
    "biased": "readings biased",
    "moving_ticks": "of them with the robot told to move",
}


@dataclass(frozen=True)
class Counts:
    """A fault's counts as describe_counts says them: the plain ones, ``(key,
    n)`` in the summary's order; then each robot's, ``(robot, ((key, n),
    ...))`` by number, its ticks first."""

    plain: tuple[tuple[str, Any], ...] = ()
    robots: tuple[tuple[int, tuple[tuple[str, Any], ...]], ...] = ()


def counts_of(counts: Mapping[str, Any]) -> Counts:
    """A fault's counts (``{"dropped": 12, "R2 ticks": 40, ...}``) grouped as ``Counts``."""
    plain, robots = [], {}
    for key, n in counts.items():
        robot, _, what = key.partition(" ")
        if what and robot.startswith("R") and robot[1:].isdigit():
            robots.setdefault(int(robot[1:]), {})[what] = n
        else:
            plain.append((key, n))
    grouped = []
    for rid in sorted(robots):
        said = robots[rid]
        ticks = [("ticks", said.pop("ticks"))] if "ticks" in said else []
        grouped.append((rid, (*ticks, *said.items())))
    return Counts(tuple(plain), tuple(grouped))


def describe_counts(counts: Mapping[str, Any]) -> str:
    """``{"dropped": 12}`` -> "12 messages dropped"; ``{"R2 ticks": 40,
    "R2 blacked_out": 38}`` -> "R2: on for 40 ticks, 38 readings blacked out";
    a key it does not know is kept as it is (``counts_of``)."""
    return _say_counts(counts_of(counts))


def _say_counts(grouped: Counts) -> str:
    out = [
        f"{n} message{'s' if n != 1 else ''} {LINK_EFFECT_WORDS[key]}" if key in LINK_EFFECT_WORDS else f"{key} {n}"
        for key, n in grouped.plain
    ]
    for rid, said in grouped.robots:
        words = [f"on for {n} ticks" if k == "ticks" else f"{n} {ROBOT_EFFECT_WORDS.get(k, k)}" for k, n in said]
        out.append(f"R{rid}: {', '.join(words)}")
    return "; ".join(out)


@dataclass(frozen=True)
class FaultSaid:
    """One scheduled fault of the summary as describe_fault says it: ``ended``,
    the run's ticks when it ended at or before the fault's ``start`` tick
    (None: it started); its events, ``(robot, tick, (event, ...))`` for the
    events of one robot at one tick; its counts; the robots whose killed agent
    left its counts partial (or unwritten, with no counts)."""

    fault: Any
    start: Any = None
    ended: int | None = None
    events: tuple[tuple[Any, Any, tuple[str, ...]], ...] = ()
    counts: Counts = Counts()
    partial_for: tuple[Any, ...] = ()


def fault_said(f: Mapping[str, Any], ticks: Any = None) -> FaultSaid:
    """One scheduled fault of the summary (and the run's ``ticks``) as a ``FaultSaid``."""
    start = f.get("start_tick")
    if isinstance(ticks, int) and isinstance(start, int) and start >= ticks:
        return FaultSaid(f.get("fault"), start, ended=ticks)
    said: list[tuple[Any, Any, list[str]]] = []  # events of one robot at one tick: one phrase
    for e in f.get("events") or []:
        if said and said[-1][:2] == (e.get("robot"), e.get("tick")):
            said[-1][2].append(str(e.get("event")))
        else:
            said.append((e.get("robot"), e.get("tick"), [str(e.get("event"))]))
    cut = f.get("counts_partial_for")
    return FaultSaid(
        f.get("fault"),
        start,
        events=tuple((robot, tick, tuple(events)) for robot, tick, events in said),
        counts=counts_of(f.get("counts") or {}),
        partial_for=tuple(cut) if cut else (),
    )


def describe_fault(f: Mapping[str, Any], ticks: Any = None) -> str:
    """One scheduled fault of the summary, with what it did, as a line; one
    whose start the run never reached (it ended early: the leader's path was
    done) says so (``fault_said``)."""
    it = fault_said(f, ticks)
    if it.ended is not None:
        return f"{it.fault}: never started: the run ended at tick {it.ended}, before its tick {it.start}"
    parts = []
    for robot, tick, events in it.events:
        what = events[0] if len(events) == 1 else f"{', '.join(events[:-1])} and {events[-1]}"
        parts.append(f"{what}{f' R{robot}' if robot is not None else ''} at tick {tick}")
    counts = _say_counts(it.counts)
    if it.partial_for:
        who = ", ".join(f"R{r}" for r in it.partial_for)
        if counts:
            counts += f" (at least: {who}'s agent was killed, and its counts end at its last stats write)"
        else:
            counts = f"not counted: {who}'s agent was killed before it wrote its counts of this fault"
    parts += describe_recoveries(f)
    said = "; ".join(x for x in ("; ".join(parts), counts) if x)
    return f"{it.fault}" + (f": {said}" if said else "")


STALL_WORDS = {
    "stalled": "stalled (its deadlines missed in a row; no longer waited for)",
    "answering again": "answering again",
    "lost while stalled": "lost after its stall: the clock held for it",
    "not back in time": "not back in time: the run went on without it",
}


def describe_stall(e: Mapping[str, Any]) -> str:
    """One event of a robot that fell silent in lockstep (world.stalls) as a sentence."""
    what = STALL_WORDS.get(str(e.get("event")), str(e.get("event")))
    return f"robot {e.get('robot')} {what} at tick {e.get('tick')}, sim t={num(e.get('time_s'), '.2f')} s"
