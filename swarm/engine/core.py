"""The engine: one lockstep run of a scenario, tick by tick, in this process.

It drives the world's tick (world.tick.WorldTick) and every robot's agent
(engine.agents: its role behind the agent process's own Router) the way the
world process (nodes.world.node, its LockstepClock) and the agent processes
(nodes.agent.node) drive them, without Zenoh. Tick k:

- the fault calls of tick k, the world's side and the agents' (a restart's
  kill takes the robot's agent away, its "start" brings a fresh one, which
  the lockstep world waits for and re-admits at once); the robots whose
  agent is back;
- the tick's observations, followers first: each robot's agent takes its
  own as bytes, answers it (the code to the followers, then the command to
  the world) and prepares the next tick;
- the world records the last tick's metrics, takes the commands (a robot
  with none misses the tick, as at the lockstep deadline), closes the tick
  and steps;
- the leader's formation code reaches every follower's inbox before tick
  k + 1's observation, as its put precedes the command the world waited for.

So the processes add nothing to the run's figures: its trajectory digest is
``swarm run --mode lockstep``'s (tests/system/test_engine.py). What depends
on processes' timing is not here: a process too slow for the lockstep
deadline, an agent frozen beyond the Zenoh lease, a logger.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from formation_swarm.common.faults import Fault
from formation_swarm.engine import faults as engine_faults
from formation_swarm.engine.agents import Agents
from formation_swarm.engine.result import EngineResult, result, world_stats
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.keys import ScenarioWarning
from formation_swarm.world.kinematics import Pose
from formation_swarm.world.process_faults import FREEZE, KILL, THAW, Call
from formation_swarm.world.tick import WorldTick

FaultLike = Fault | str | Mapping[str, Any]
DONE = {KILL: "killed", FREEZE: "frozen", THAW: "thawed"}  # the events of the calls, as swarm run names them


class Engine:
    """One lockstep run in one process.

    ``Engine(scenario, seed=None, overrides=None, faults=())``: a shipped
    scenario's name or a TOML file; the seed of every random draw (None: the
    scenario's ``run.seed``); scenario keys to override (``{"controller.law":
    "my_controller:Mine"}``); faults added to the scenario's (docs/faults.md's
    grammar). A bad scenario, key or fault raises ValueError, as does a
    fault that needs processes (a kill, any fault of the logger).

    ``step()`` runs one tick, ``run()`` runs to the end and returns the
    :class:`EngineResult`; ``reset(seed)`` starts over."""

    def __init__(
        self,
        scenario: str | Path,
        *,
        seed: int | None = None,
        overrides: Mapping[str, Any] | None = None,
        faults: Sequence[FaultLike] | FaultLike = (),
    ) -> None:
        if overrides is not None and not isinstance(overrides, Mapping):
            raise ValueError(f"overrides must map scenario keys to values, got {type(overrides).__name__}")
        self._path = scenario
        self._overrides = dict(overrides or {})
        # One given alone ("restart agent-3@20s") is one, not a sequence of letters.
        self._faults = [faults] if isinstance(faults, (str, Mapping, Fault)) else list(faults)
        if seed is not None and self._overrides.get("run.seed", seed) != seed:
            raise ValueError(f"seed {seed} and run.seed {self._overrides['run.seed']!r} in the overrides: give it once")
        self._sc = self._load(seed)
        engine_faults.check(self._sc.faults)
        self.reset()

    def _load(self, seed: int | None) -> scenario_mod.Scenario:
        ov = self._overrides if seed is None else {**self._overrides, "run.seed": seed}
        return scenario_mod.load(self._path, ov, self._faults)

    def reset(self, seed: int | None = None) -> None:
        """Start the run over at tick 0, with ``seed`` (None: the last run's):
        the same seed gives the same run, bit for bit."""
        if seed is not None and seed != self._sc.seed:
            with warnings.catch_warnings():  # said when the scenario was first loaded
                warnings.simplefilter("ignore", ScenarioWarning)
                self._sc = self._load(seed)
        sc = self._sc
        self._world = WorldTick(sc, sc.seed, lockstep=True, wall_s=self._sim_s)
        self._agents = Agents(sc, sc.seed)
        for rid in sc.robots:
            self._agents.start(rid)
            self._world.agent_token(rid, True)
        self._events: list[dict[str, Any]] = []
        self._wall_s = 0.0  # spent stepping
        self._result: EngineResult | None = None

    # -- what the run is -------------------------------------------------------------
    @property
    def scenario(self) -> scenario_mod.Scenario:
        """The scenario as run (overrides, faults and seed applied)."""
        return self._sc

    @property
    def seed(self) -> int:
        return self._sc.seed

    @property
    def tick(self) -> int:
        """The ticks run so far."""
        return self._world.engine.tick

    @property
    def time_s(self) -> float:
        """The sim time reached, in s."""
        return self._world.engine.time_s

    @property
    def poses(self) -> dict[int, Pose]:
        """Every robot's true pose now, by id: (x_m, y_m, theta_rad), world frame."""
        return {rid: r.pose for rid, r in self._world.engine.robots.items()}

    @property
    def running(self) -> bool:
        """Whether there is a tick to run: the duration not reached, the leader not done."""
        return self._world.running

    def _sim_s(self) -> float:
        """What the fault log records as wall time: the sim time (nothing here waits)."""
        return self._world.engine.time_s

    # -- the run ------------------------------------------------------------------------
    def step(self) -> bool:
        """Run one tick; whether the run goes on (False once it has ended:
        then a step does nothing)."""
        world = self._world
        if not world.running:
            return False
        t0 = time.perf_counter()
        world.start(self._sim_s())
        self._process_faults()
        commands, codes = self._answers()
        world.record()
        for rid, payload in commands:
            world.receive(rid, payload)
        if waiting := world.waiting():  # no answer: the lockstep deadline passes, stopped for this step
            world.miss(waiting)
            self._agents.notes += [f"world: {line}" for line in world.stall(waiting)]
        world.close()
        world.step()
        self._agents.codes(codes)  # the router's copy to every follower's inbox
        self._wall_s += time.perf_counter() - t0
        return world.running

    def run(self) -> EngineResult:
        """Run to the end (from where the run is) and return its result."""
        while self.step():
            pass
        if self._result is None:
            world = self._world
            world.finish()
            reason = summary_mod.LEADER_FINISHED if world.leader_done else summary_mod.DURATION_REACHED
            stats = world_stats(world, end_reason=reason, ended_at_s=self.time_s, wall_s=self._wall_s)
            agents = self._agents
            self._result = result(self._sc, stats, agents.stats(), self._events, agents.notes)
        return self._result

    def _answers(self) -> tuple[list[tuple[int, bytes]], list[bytes]]:
        """Each observed robot's command to the tick's observation, and the
        leader's code (routed after the step), as bytes."""
        agents, commands, codes = self._agents, [], []
        for rid, obs in self._world.observations():
            if rid not in agents:  # no agent hears it (none is observed without one in lockstep)
                continue
            answer = agents.answer(rid, obs.to_bytes())
            if answer is None:
                continue
            if answer.code is not None:
                codes.append(answer.code.to_bytes())
            commands.append((rid, answer.command.to_bytes()))
            agents.prepare(rid)
        return commands, codes

    def _process_faults(self) -> None:
        """This tick's fault calls, the world's side and the agents', each an
        event as ``swarm run``'s launcher records it; then the robots whose
        agent is back are re-admitted."""
        world, agents = self._world, self._agents
        for call in world.calls_due():
            if (rid := world.apply_call(call)) is not None:  # a restart's "start": the world waits for it
                self._event("started", agents.start(rid), call)
                world.agent_token(rid, True)
            elif call.action == KILL and call.robot in agents:
                self._event(DONE[KILL], agents.stop(call.robot), call)
                world.agent_token(call.robot, False)
            elif call.action in (FREEZE, THAW) and call.robot in agents:
                self._event(DONE[call.action], agents.names[call.robot], call)
        world.readmit(agents.__contains__)

    def _event(self, event: str, process: str, call: Call) -> None:
        self._events.append(
            {"event": event, "process": process, "fault": str(call.fault), "tick": call.tick, "sim_time_s": self.time_s}
        )
