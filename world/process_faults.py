"""The world's side of process faults (kill, restart, freeze) and of agents
that come and go: which call is due at which tick, which robots a lockstep
tick skips or waits long for, and when a robot whose agent returns is
re-admitted.

The world drives process faults on its own clock: at a fault's tick it
publishes a call (kill, start, freeze, thaw) that the process's owner (the
launcher) executes, and it applies the fault's effect on the world itself at
that tick, whatever the real signal's timing:

- kill at tick N: the robot is dead from tick N (no observation of tick N).
- restart: a kill at N; at M = ``Fault.end_tick`` the call "start"; the robot
  is re-admitted once a fresh agent's token is there (a new one, after the
  old one went away). The world process waits for it at M in lockstep.
- freeze from N to M: calls "freeze" and "thaw". In lockstep the robot gets
  no observation and is not waited for during N..M-1 (its last command holds
  until ``stale_after_s``, then it stops, like a silent robot in real time);
  its first answer after the thaw is waited for long. In real time the
  world does nothing but the calls.
- an agent whose token goes without a kill is lost: its robot stops. If its
  token comes back (a session regained after a freeze beyond the lease, a
  router restart), the robot is re-admitted as after a restart.

Everything is logged in ``fault_log`` ({tick, time_s, wall_s, fault, event,
robot}); each return gives a ``rejoins`` record (ticks and wall seconds from
the "start" call, or the loss, to the agent's first command) and
formation-error :class:`~formation_swarm.world.recovery.Recovery` records:
the returning follower's, or each follower's when the leader returns.

No Zenoh here: world.tick feeds it the liveliness changes and the
commands and makes the calls' messages; the world process
(nodes.world.node) publishes them and does the waiting.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from formation_swarm.common.faults import PROCESS
from formation_swarm.world.recovery import Recovery

if TYPE_CHECKING:
    from formation_swarm.common.faults import Fault
    from formation_swarm.world.engine import WorldEngine

KILL, START, FREEZE, THAW = "kill", "start", "freeze", "thaw"


@dataclass(frozen=True)
class Call:
    """One call to the executor: ``action`` on ``fault.target`` at ``tick``;
    ``index`` is the fault's place in the scenario's schedule."""

    tick: int
    index: int
    fault: Fault
    action: str

    @property
    def robot(self) -> int | None:
        return self.fault.robot


def calls(faults: Iterable[Fault], dt_s: float) -> dict[int, list[Call]]:
    """The calls of a fault schedule by tick, each tick's in schedule order."""
    out: dict[int, list[Call]] = {}
    for index, f in enumerate(faults):
        if f.group != PROCESS:
            continue
        start, end = f.start_tick(dt_s), f.end_tick(dt_s)
        todo = {
            "kill": [(start, KILL)],
            "restart": [(start, KILL), (end, START)],
            "freeze": [(start, FREEZE), (end, THAW)],
        }[f.kind]
        for tick, action in todo:
            if tick is not None:
                out.setdefault(tick, []).append(Call(tick, index, f, action))
    for tick_calls in out.values():
        tick_calls.sort(key=lambda c: c.index)
    return out


@dataclass
class _Agent:
    token: bool = False  # its liveliness token is there
    fresh: bool = False  # that token was declared after the robot stopped: a new (or returning) agent


@dataclass
class ProcessFaults:
    engine: WorldEngine
    faults: tuple[Fault, ...]
    lockstep: bool
    schedule: dict[int, list[Call]] = field(init=False)
    agents: dict[int, _Agent] = field(init=False)
    frozen: set[int] = field(init=False, default_factory=set)  # lockstep: not observed, not waited for
    thawing: set[int] = field(init=False, default_factory=set)  # lockstep: first answer after a thaw, waited long
    starting: dict[int, Call] = field(init=False, default_factory=dict)  # "start" called, not re-admitted yet
    rejoining: dict[int, dict[str, Any]] = field(init=False, default_factory=dict)  # back, no command yet
    fault_log: list[dict[str, Any]] = field(init=False, default_factory=list)
    rejoins: list[dict[str, Any]] = field(init=False, default_factory=list)
    deaths: list[dict[str, Any]] = field(init=False, default_factory=list)
    _stopped: dict[int, tuple[int, float, str | None, str]] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        sc = self.engine.scenario
        self.schedule = calls(self.faults, sc.dt_s)
        self.agents = {rid: _Agent() for rid in self.engine.robots}

    @property
    def dt_s(self) -> float:
        return self.engine.scenario.dt_s

    def due(self, tick: int) -> list[Call]:
        return self.schedule.get(tick, [])

    def active_fault(self, process: str, tick: int) -> Fault | None:
        """The process fault on ``process`` that covers ``tick`` (a kill covers the rest of the run)."""
        for f in self.faults:
            if f.group == PROCESS and f.target == process and f.active(tick, self.dt_s):
                return f
        return None

    def log(self, event: str, robot: int | None, fault: Fault | str | None, wall_s: float) -> None:
        eng = self.engine
        text = None if fault is None else str(fault)
        self.fault_log.append(
            {"tick": eng.tick, "time_s": eng.time_s, "wall_s": wall_s, "fault": text, "event": event, "robot": robot}
        )

    # -- the calls, at their tick ---------------------------------------------------
    def execute(self, call: Call, wall_s: float) -> None:
        """The world's side of a call, done before the tick's observations."""
        rid, f = call.robot, call.fault
        if call.action == KILL:
            self.log("killed", rid, f, wall_s)
            if rid is not None and self.engine.robots[rid].alive:
                self._stop(rid, wall_s, f, "killed")
        elif call.action == START:
            self.log("started", rid, f, wall_s)
            if rid is not None and not self.engine.robots[rid].alive:
                self.starting[rid] = call
                self._stopped[rid] = (self.engine.tick, wall_s, str(f), "restart")
        elif call.action == FREEZE:
            self.log("frozen", rid, f, wall_s)
            if rid is not None and self.lockstep:
                self.frozen.add(rid)
        else:  # THAW
            self.log("thawed", rid, f, wall_s)
            if rid is not None:
                self.frozen.discard(rid)
                if self.engine.robots[rid].alive:
                    if self.lockstep:
                        self.thawing.add(rid)
                    self._watch(rid, "thawed", str(f))

    def returning(self, rid: int) -> bool:
        """Whether ``rid`` was just thawed, or re-admitted after a scheduled fault, and has not answered since."""
        back = self.rejoining.get(rid)
        return rid in self.thawing or (back is not None and back["fault"] is not None)

    def observed(self, rid: int) -> bool:
        """Whether a live robot gets this tick's observation (and is waited for)."""
        return rid not in self.frozen

    # -- agents coming and going ------------------------------------------------------
    def token(self, rid: int, present: bool, wall_s: float, finished: bool) -> str | None:
        """A change of robot ``rid``'s agent token; a line to print when it means
        the robot is lost (its agent gone with no kill called)."""
        a = self.agents[rid]
        if present:
            a.fresh = a.fresh or not a.token
            a.token = True
            return None
        a.token = a.fresh = False
        if not self.engine.robots[rid].alive or finished:
            return None
        fault = self.active_fault(f"agent-{rid}", self.engine.tick)
        self.log("lost", rid, fault, wall_s)
        self._stop(rid, wall_s, fault, "lost")
        return f"robot {rid} lost its agent at t={self.engine.time_s:.2f} s; stopped until it returns"

    def _stop(self, rid: int, wall_s: float, fault: Fault | None, cause: str) -> None:
        eng = self.engine
        eng.kill(rid)
        self.agents[rid].fresh = False  # a token there now is the old agent's
        self.frozen.discard(rid)
        self.thawing.discard(rid)
        self.rejoining.pop(rid, None)
        self.deaths.append(
            {"robot": rid, "tick": eng.tick, "time_s": eng.time_s, "pose": list(eng.robots[rid].pose), "cause": cause}
        )
        self._stopped[rid] = (eng.tick, wall_s, None if fault is None else str(fault), cause)

    def back(self, rid: int) -> bool:
        """Whether a stopped robot's agent is back: a token declared since it stopped."""
        a = self.agents[rid]
        return not self.engine.robots[rid].alive and a.token and a.fresh

    def returned(self) -> list[int]:
        """The stopped robots whose agent is back (asked every tick: only the stopped ones are looked at)."""
        return sorted(rid for rid in self._stopped if self.back(rid))

    def readmit(self, rid: int, wall_s: float) -> None:
        """The robot is alive again from this tick: observed and waited for."""
        eng = self.engine
        eng.revive(rid)
        self.agents[rid].fresh = False
        self.starting.pop(rid, None)
        since_tick, since_wall, fault, cause = self._stopped.pop(rid, (eng.tick, wall_s, None, "lost"))
        self.log("readmitted", rid, fault, wall_s)
        self.rejoining[rid] = {
            "robot": rid,
            "fault": fault,
            "cause": cause,
            "since_tick": since_tick,
            "since_wall_s": since_wall,
            "readmitted_tick": eng.tick,
        }
        self._watch(rid, "readmitted", fault)

    def _watch(self, rid: int, event: str, fault: str | None) -> None:
        sc = self.engine.scenario
        # A follower's own error; when the leader returns, each follower's.
        for watched in sc.follower_ids if rid == sc.leader.robot_id else (rid,):
            self.engine.recoveries.append(Recovery(rid, event, fault, self.engine.tick, (watched,), self.dt_s))

    def not_back(self, rid: int, wall_s: float) -> None:
        """A restart whose fresh agent did not come in time: the robot stays stopped."""
        call = self.starting.pop(rid, None)
        self.log("not back", rid, None if call is None else call.fault, wall_s)

    def answered(self, rid: int, wall_s: float) -> None:
        """A command of robot ``rid`` was taken: the first one after a return is its rejoining."""
        self.thawing.discard(rid)
        back = self.rejoining.pop(rid, None)
        if back is None:
            return
        eng = self.engine
        self.log("rejoined", rid, back["fault"], wall_s)
        back.update(
            {
                "rejoined_tick": eng.tick,
                "ticks_to_rejoin": eng.tick - back["since_tick"],
                "wall_s_to_rejoin": wall_s - back.pop("since_wall_s"),
            }
        )
        self.rejoins.append(back)

    def stats(self) -> dict[str, Any]:
        pending = [
            dict(b, rejoined_tick=None, ticks_to_rejoin=None, wall_s_to_rejoin=None) for b in self.rejoining.values()
        ]
        for b in pending:
            b.pop("since_wall_s", None)
        return {
            "fault_log": self.fault_log,
            "rejoins": self.rejoins + pending,
            "recoveries": [r.as_dict() for r in self.engine.recoveries],
            "deaths": self.deaths,
        }
