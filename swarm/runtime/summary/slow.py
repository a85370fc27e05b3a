"""Controllers too slow for their run, from the agents' stats (their step
times, agents.step_times; a call under way, nodes.agent.watch) and the
world's (each robot's lockstep misses, world.misses):

``step_times``
    each robot's steps: ``{steps, median_s, max_s, max_tick, over_tick, tick_s}``.
``not_reproducible``
    lockstep: each robot that missed a deadline no scheduled fault explains,
    with its law, those misses, the first one's tick, its step time and
    ``run.lockstep_deadline_s``. Such a run fails: it would not fly again as it flew.
``slow_controllers``
    real time: each robot whose steps took longer than the tick, with its
    law and its median and longest step. Said, not a failure.
``hung_controllers``
    each robot whose controller hung: a call of it had not returned when its
    agent left without it after the run's end (nodes.agent.watch), or when
    the launcher killed the agent at its stop timeout. Its law, the call,
    its tick, how long it had run (at the last note) and ``ended``: "left"
    or "killed at the stop timeout". Such a run fails.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

from formation_swarm.runtime.children import KILLED_AT_STOP_TIMEOUT
from formation_swarm.spec.laws import follower_law

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

# How a hung controller's agent ended (``hung_controllers``' "ended").
LEFT = "left"  # on its own, after the run's end (nodes.agent.watch)
KILLED = "killed at the stop timeout"  # by the launcher


def seconds(value: Any) -> str:
    """A step time in words: "2.50 s", "1.3 ms", "0.012 ms"; "-" when unknown."""
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return "-"
    if value >= 1.0:
        return f"{value:.2f} s"
    return f"{value * 1e3:.1f} ms" if value >= 1e-3 else f"{value * 1e3:.3f} ms"


def _g(value: Any) -> str:
    """A setting in words: 2.0 -> "2", 0.05 -> "0.05"; anything else as it is."""
    return f"{value:g}" if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)


def _law(sc: Scenario, robot: int) -> dict[str, Any]:
    """Robot ``robot``'s role and what decides its steps, as spec.laws names it:
    a follower's law, the leader's policy (None: no robot of the scenario)."""
    if robot in sc.followers:
        return {"role": "follower", "law": follower_law(sc.followers[robot])}
    leader = robot == sc.leader.robot_id
    return {"role": "leader" if leader else None, "law": sc.leader.policy if leader else None}


def _who(e: Mapping[str, Any]) -> str:
    """Who steps, in words: "robot 3's controller (pkg.mod:Cls)", "robot 1's policy (path)"."""
    return f"robot {e.get('robot')}'s {'policy' if e.get('role') == 'leader' else 'controller'} ({e.get('law')})"


def step_times(parts: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Each robot's step times by id, from its agents' stats: a restarted
    robot's agents summed, its longest step kept, and the median of the
    agent with the most steps."""
    out: dict[str, dict[str, Any]] = {}
    for name, part in sorted(parts.items()):
        st = part.get("step_time") if name.startswith("agent-") and isinstance(part, Mapping) else None
        if not isinstance(st, Mapping) or not isinstance(part.get("robot"), int):
            continue
        rid, st = str(part["robot"]), dict(st)
        have = out.setdefault(rid, st)
        if have is st:
            continue
        merged = dict(st if (st.get("steps") or 0) > (have.get("steps") or 0) else have)
        merged["steps"] = (have.get("steps") or 0) + (st.get("steps") or 0)
        merged["over_tick"] = (have.get("over_tick") or 0) + (st.get("over_tick") or 0)
        longest = max((have, st), key=lambda s: s.get("max_s") or 0.0)
        merged["max_s"], merged["max_tick"] = longest.get("max_s"), longest.get("max_tick")
        out[rid] = merged
    return out


def not_reproducible(world: Mapping[str, Any], parts: Mapping[str, Any], sc: Scenario) -> list[dict[str, Any]]:
    """Lockstep: each robot that missed a deadline no scheduled fault explains."""
    if world.get("mode") != "lockstep":
        return []
    times = step_times(parts)
    out = []
    for rid, m in (world.get("robot_misses") or {}).items():
        if not (isinstance(m, Mapping) and str(rid).isdigit()):
            continue
        unexplained = int(m.get("misses") or 0) - int(m.get("by_faults") or 0)
        if unexplained > 0:
            st = times.get(str(rid), {})
            out.append(
                {
                    "robot": int(rid),
                    **_law(sc, int(rid)),
                    "misses": unexplained,
                    "first_tick": m.get("first_tick"),
                    "step_median_s": st.get("median_s"),
                    "step_max_s": st.get("max_s"),
                    "deadline_s": sc.lockstep_deadline_s,
                }
            )
    return sorted(out, key=lambda e: e["robot"])


def slow_controllers(world: Mapping[str, Any], parts: Mapping[str, Any], sc: Scenario) -> list[dict[str, Any]]:
    """Real time: each robot whose steps took longer than the tick."""
    if world.get("mode") != "realtime":
        return []
    out = []
    for rid, st in step_times(parts).items():
        if st.get("over_tick"):
            keep = ("steps", "over_tick", "median_s", "max_s", "max_tick")
            out.append({"robot": int(rid), **_law(sc, int(rid)), **{k: st.get(k) for k in keep}, "tick_s": sc.dt_s})
    return sorted(out, key=lambda e: e["robot"])


def hung_controllers(
    parts: Mapping[str, Any], events: Iterable[Mapping[str, Any]], sc: Scenario
) -> list[dict[str, Any]]:
    """Each robot whose agent left without a call that had not returned, or
    was killed at the stop timeout in one."""
    killed = {e.get("process") for e in events if e.get("event") == KILLED_AT_STOP_TIMEOUT}
    out = []
    for name, part in sorted(parts.items()):
        call = part.get("in_step") if isinstance(part, Mapping) else None
        if not (isinstance(call, Mapping) and isinstance(rid := part.get("robot"), int)):
            continue
        if call.get("left") or name in killed:
            what = {k: call.get(k) for k in ("call", "tick", "for_s")}
            ended = LEFT if call.get("left") else KILLED
            out.append({"robot": rid, **_law(sc, rid), "process": name, **what, "ended": ended})
    return out


def describe_hung(hung: Iterable[Mapping[str, Any]]) -> list[str]:
    """Each hung controller in words."""
    out = []
    for h in hung:
        left = h.get("ended") == LEFT
        how = "its agent left without it after the run's end" if left else f"its agent was {KILLED}"
        where = f"its {h.get('call')} of tick {h.get('tick')}"
        out.append(f"{_who(h)} hung in {where} ({seconds(h.get('for_s'))} in it; {how})")
    return out


def describe_not_reproducible(entries: Iterable[Mapping[str, Any]], hung: Iterable[Any] = ()) -> str | None:
    """The robots that make a lockstep run not reproducible, in words (None:
    none); a robot of ``hung`` (ids) is said in short, its hang said apart."""
    said, hung = [], set(hung)
    for e in entries:
        n = e.get("misses")
        if e.get("robot") in hung:
            who, step = f"robot {e.get('robot')}", "its controller hung"
        else:
            who = _who(e)
            step = f"its step took {seconds(e.get('step_median_s'))} (median; longest {seconds(e.get('step_max_s'))})"
        said.append(
            f"{who} missed {n} lockstep deadline{'s' if n != 1 else ''} from tick {e.get('first_tick')}: {step}, "
            f"and run.lockstep_deadline_s is {_g(e.get('deadline_s'))} s"
        )
    return "not reproducible: " + "; ".join(said) if said else None


def describe_slow(s: Mapping[str, Any]) -> str:
    """One slow controller of a real-time run in words."""
    return (
        f"{_who(s)} took longer than the tick ({_g(s.get('tick_s'))} s) in {s.get('over_tick')} of "
        f"{s.get('steps')} steps: median {seconds(s.get('median_s'))}, longest {seconds(s.get('max_s'))}"
    )
