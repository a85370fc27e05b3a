"""What a run's recording misses: by loss (``recording_gap``: a lockstep
run's logger took less than was sent, so its recorded metrics are wrong and
a sweep runs it again) or by the logger's end before the run's
(``recording_cut``: a fault killed it, by design, or it was lost otherwise:
``logger_lost``, a failed run).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from formation_swarm.runtime.children import describe_exit
from formation_swarm.runtime.summary.links import robot_of


def recording_cut(summary: Mapping[str, Any]) -> str | None:
    """Where the logger was lost, what that did to the recording, in words
    (None: it was not). Killed by a fault, by the fault's design, not a loss
    to retry (recording_gap); lost otherwise (killed from outside, crashed,
    cut off), at the tick the world saw its token go. Either way the
    recording ends there, minus what the logger had not yet written."""
    events = [e for e in summary.get("events") or [] if isinstance(e, Mapping) and e.get("process") == "logger"]
    world = (summary.get("parts") or {}).get("world") or {}
    fast = (
        "; a lockstep run passes many ticks in a second, so it may hold none"
        if summary.get("mode") == "lockstep"
        else ""
    )
    unwritten = f"without what the logger had not yet written (up to its last second of wall time{fast})"
    for e in events:
        if e.get("event") == "killed":
            return f"the logger was killed{_when(e.get('sim_time_s'))}: the recording ends before that, {unwritten}"
    if (lost := logger_lost(world, events)) is None:
        return None
    return (
        f"{lost}: the recording ends there, {unwritten}; its file has no end (rerun rrd verify fails on it, "
        "what it holds still reads)"
    )


def logger_lost(world: Mapping[str, Any], events: Sequence[Mapping[str, Any]]) -> str | None:
    """How the logger was lost outside the fault schedule, when (the world's
    record of its token going, ``logger_lost`` in its stats, else the
    launcher's of its exit), in words; None when it was not (or a fault
    killed it). A logger that left before the run's first tick lost nothing
    of a recording: the run's end names why it did not start."""
    mine = [e for e in events if isinstance(e, Mapping) and e.get("process") == "logger"]
    if any(e.get("event") == "killed" for e in mine):
        return None
    exited = next((e for e in mine if e.get("event") == "exited" and isinstance(e.get("code"), int)), None)
    if exited is not None and _before_start(exited.get("sim_time_s")):
        exited = None
    seen = world.get("logger_lost")
    if exited is None and not isinstance(seen, Mapping):
        return None
    how = f"the logger {describe_exit(exited['code'])}" if exited is not None else "the logger's token went"
    if isinstance(seen, Mapping):
        return f"{how}{_when(seen.get('time_s'), seen.get('tick'))}, outside the fault schedule"
    return f"{how}{_when(exited.get('sim_time_s'), exited.get('tick'))}, outside the fault schedule"


def _before_start(t: Any) -> bool:
    """Whether an event's sim time says it came before tick 0 (the launcher writes -1 then)."""
    return isinstance(t, (int, float)) and t < 0


def _when(t: Any, tick: Any = None) -> str:
    at = f" at sim t={t:.2f} s" if isinstance(t, (int, float)) and t >= 0 else ""
    return at + (f" (tick {tick})" if isinstance(tick, int) and at else "")


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
    logger = (summary.get("parts") or {}).get("logger") or {}
    ticks = logger.get("ticks") if isinstance(logger.get("ticks"), Mapping) else None
    sent_truth = (summary.get("messages") or {}).get("truth_sent")
    return _truth_gap(logger, ticks, sent_truth) or _telemetry_gap(summary, ticks, sent_truth)


def _truth_gap(logger: Mapping[str, Any], ticks: Mapping[str, Any] | None, sent_truth: Any) -> str | None:
    """The world's ticks of truth the logger did not take."""
    got = (logger.get("messages") or {}).get("truth")
    if isinstance(got, int) and isinstance(sent_truth, int) and got < sent_truth:
        where = _missing_ticks("truth", (ticks or {}).get("0"), sent_truth)
        return f"the logger recorded {got} of the {sent_truth} ticks the world sent" + (
            f" (missing: {where})" if where else ""
        )
    return None


def _telemetry_gap(summary: Mapping[str, Any], ticks: Mapping[str, Any] | None, sent_truth: Any) -> str | None:
    """The first follower whose telemetry the logger took less of than it
    answered ticks, but for robots whose agent a fault killed or restarted."""
    parts = summary.get("parts") or {}
    faulted = {
        robot_of(e.get("process"))
        for e in summary.get("events") or []
        if isinstance(e, Mapping) and e.get("event") in ("killed", "started")
    }
    answered = _answered(parts)
    if ticks is None:  # a logger's stats from before per-sender ticks: the totals
        total = ((parts.get("logger") or {}).get("messages") or {}).get("telemetry")
        if not faulted and answered and isinstance(total, int) and total < sum(answered.values()):
            return (
                f"the logger recorded {total} of the {sum(answered.values())} telemetry messages the followers "
                "sent (one per tick answered)"
            )
        return None
    for rid, sent in sorted(answered.items()):
        if rid not in faulted and (why := _robot_gap(rid, sent, ticks.get(str(rid)), sent_truth)) is not None:
            return why
    return None


def _answered(parts: Mapping[str, Any]) -> dict[int, int]:
    """Per follower, the ticks its agents answered (a restarted one's added)."""
    answered: dict[int, int] = {}
    for name, p in parts.items():
        rid = robot_of(name)
        if (
            isinstance(p, Mapping)
            and p.get("role") == "follower"
            and rid is not None
            and isinstance(p.get("answered"), int)
        ):
            answered[rid] = answered.get(rid, 0) + p["answered"]
    return answered


def _robot_gap(rid: int, sent: int, t: Any, sent_truth: Any) -> str | None:
    """What the logger missed of one follower's ``sent`` telemetry messages,
    from its tick stats ``t`` (None: it took them all, or its stats do not say)."""
    if not isinstance(t, Mapping):  # none of its telemetry reached the logger
        if sent > 0:
            return f"the logger recorded none of the {sent} telemetry messages R{rid} sent (one per tick answered)"
        return None
    first, last, missing = t.get("first"), t.get("last"), t.get("missing", 0)
    if not (isinstance(first, int) and isinstance(last, int) and isinstance(missing, int)):
        return None
    if (got := last - first + 1 - missing) < sent:
        where = _missing_ticks(f"R{rid}'s telemetry", t, sent_truth)
        return f"the logger recorded {got} of the {sent} telemetry messages R{rid} sent (one per tick answered)" + (
            f" (missing: {where})" if where else ""
        )
    return None


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
