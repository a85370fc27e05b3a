"""Why a run ended (``end_reason``: one of ``END_REASONS``) and, in words,
why it ended or why a run that ended still failed: a process that exited on
its own, a host lost, a leader or every follower without its agent, a
follower's controller that failed.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, NamedTuple

from formation_swarm.runtime.children import describe_exit

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


def world_failed(events: list[Mapping[str, Any]]) -> str | None:
    """How the world ended on its own with an error (killed from outside, a
    crash), from the launcher's "exited" event, in words; None if it did not.
    The world takes the run with it: it is the run's failure."""
    for e in events:
        if e.get("event") == "exited" and e.get("process") == "world" and isinstance(e.get("code"), int):
            if e["code"] == 0:
                return None
            t = e.get("sim_time_s")
            when = (
                f"after sim t={t:.2f} s (its last status)"
                if isinstance(t, (int, float)) and t >= 0
                else "before the run started"
            )
            return f"the world {describe_exit(e['code'])} {when}: the run ended"
    return None


def describe_waited(world: Mapping[str, Any]) -> str | None:
    """What the world gave up waiting for before tick 0 and for how long (its
    stats' ``waited_for``), in words; None if it did not give up."""
    waited = world.get("waited_for")
    if not isinstance(waited, Mapping) or not isinstance(t := waited.get("timeout_s"), (int, float)):
        return None
    return f"the world gave up after {t:g} s (--peers-timeout): {waited.get('missing') or 'its peers did not appear'}"


def describe_host_lost(ev: Mapping[str, Any]) -> str:
    """A "host lost" event of a run on hosts (its token went mid-run) as a sentence."""
    t = ev.get("sim_time_s")
    when = f"at sim t={t:.2f} s" if isinstance(t, (int, float)) and t >= 0 else "before the run started"
    robots = [str(r) for r in ev.get("robots") or []]
    dead = f"robot{'s' if len(robots) > 1 else ''} {', '.join(robots)} counted dead" if robots else "it ran no robot"
    return f"host {ev.get('host')} lost {when}: {dead}"


class LostAgents(NamedTuple):
    """Whose agents a run lost for good (``lost_agents``): the leader's
    (``robots`` its id, ``time_s`` when), or every follower's (``time_s`` None)."""

    leader: bool
    robots: tuple[int, ...]
    time_s: float | None


def lost_agents(world: Mapping[str, Any], sc: Scenario) -> LostAgents | None:
    """Why a run that ran to its end still failed: its leader lost its agent
    (the formation could not fly its path), or every follower did, for good
    (a robot whose agent came back, after a restart say, is not lost). None if not."""
    dead = world.get("dead_robots")  # at the end of the run; None in stats that do not say
    deaths = {d.get("robot"): d for d in world.get("deaths", []) if dead is None or d.get("robot") in dead}
    leader = sc.leader.robot_id
    if leader in deaths:
        return LostAgents(True, (leader,), deaths[leader].get("time_s", 0.0))
    if sc.follower_ids and all(rid in deaths for rid in sc.follower_ids):
        return LostAgents(False, tuple(sc.follower_ids), None)
    return None


def robots_lost(world: Mapping[str, Any], sc: Scenario) -> str | None:
    """``lost_agents`` in words; None if the run lost neither."""
    if (lost := lost_agents(world, sc)) is None:
        return None
    if lost.leader:
        return f"the leader (robot {lost.robots[0]}) lost its agent at t={lost.time_s:.2f} s"
    return f"every follower ({', '.join(map(str, lost.robots))}) lost its agent"


def controller_failures(parts: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Every follower controller that failed (agents.follower_role), from the
    agents' stats (``parts``: process name -> stats): robot, tick, error, law,
    by tick. An agent restarted after its controller failed may fail again."""
    out = []
    for name, part in parts.items():
        failure = part.get("controller_failure") if name.startswith("agent-") and isinstance(part, Mapping) else None
        if isinstance(failure, Mapping):
            out.append({"robot": part.get("robot"), **failure})
    return sorted(out, key=lambda f: (f.get("tick") or 0, f.get("robot") or 0))


def describe_controller_failures(failures: list[Mapping[str, Any]]) -> str | None:
    """The failed controllers in words (None: none): the run failed."""
    if not failures:
        return None
    said = [
        f"robot {f.get('robot')}'s controller ({f.get('law')}) at tick {f.get('tick')}: {f.get('error')}"
        for f in failures
    ]
    return "a controller failed, its robot stopped: " + "; ".join(said)
