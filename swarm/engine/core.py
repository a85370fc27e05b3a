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

A caller may drive robots (the learning adapters, formation_swarm.gym):
:meth:`Engine.observe` runs a tick up to the robots' answers, which
:attr:`Engine.inputs` and :attr:`Engine.wheels` then show, and
``step(actions)`` finishes it with the given wheel speeds in place of those
robots' answers. Each follower's controller is watched (engine.drive) to
keep its input; nothing else changes, so a run with no actions is the run.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from formation_swarm.agents.controller import FollowerInput
from formation_swarm.common.faults import Fault
from formation_swarm.engine import faults as engine_faults
from formation_swarm.engine.agents import Agents
from formation_swarm.engine.drive import Watched, checked_actions
from formation_swarm.engine.result import EngineResult, result, world_stats
from formation_swarm.protocol.messages import Command
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.keys import ScenarioWarning
from formation_swarm.world.kinematics import Pose
from formation_swarm.world.process_faults import FREEZE, KILL, THAW, Call
from formation_swarm.world.tick import WorldTick

FaultLike = Fault | str | Mapping[str, Any]
Actions = Mapping[int, tuple[float, float]]  # robot id -> (left_mps, right_mps) for one tick
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
    :class:`EngineResult`; ``reset(seed)`` starts over. ``observe()`` and
    ``step(actions)`` drive robots (the module's docstring)."""

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
        if (old := getattr(self, "_agents", None)) is not None:
            old.close()  # the last run's controllers and policy: the roles are built afresh
        self._world = WorldTick(sc, sc.seed, lockstep=True, wall_s=self._sim_s)
        self._agents = Agents(sc, sc.seed)
        self._inputs: dict[int, FollowerInput] = {}  # each follower's input of the tick observed last
        # The tick observed and not yet stepped: each robot's command as its role answered, the leader's codes.
        self._open: tuple[dict[int, Command], list[bytes]] | None = None
        for rid in sc.robots:
            self._start(rid)
            self._world.agent_token(rid, True)
        self._events: list[dict[str, Any]] = []
        self._wall_s = 0.0  # spent stepping
        self._result: EngineResult | None = None

    def _start(self, rid: int) -> str:
        """A fresh agent for robot ``rid``, its controller watched if it is a follower's; its name."""
        name = self._agents.start(rid)
        role = self._agents.live[rid].role
        if (law := getattr(role, "controller", None)) is not None:
            role.controller = Watched(law, rid, self._inputs)
        return name

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

    @property
    def end_reason(self) -> str | None:
        """Why the run has ended (``leader_finished`` or ``duration_reached``); None while it runs."""
        if self.running:
            return None
        return summary_mod.LEADER_FINISHED if self._world.leader_done else summary_mod.DURATION_REACHED

    @property
    def inputs(self) -> dict[int, FollowerInput]:
        """What each follower's controller got at the tick observed last
        (agents.controller.FollowerInput), by robot id: those whose controller
        stepped (not one killed, frozen, failed, or whose observation was lost)."""
        return dict(self._inputs)

    @property
    def wheels(self) -> dict[int, tuple[float, float]]:
        """The wheel speeds (left_mps, right_mps) each robot answered the tick
        observed and not yet stepped with, by robot id, as its own law gave
        them; empty when no tick is open."""
        if self._open is None:
            return {}
        return {rid: (cmd.left_mps, cmd.right_mps) for rid, cmd in self._open[0].items()}

    def formation_errors(self) -> dict[int, float]:
        """Each follower's formation error now, in m, by robot id: its distance
        from its true virtual target (eq. 2 on the true poses, in the formation
        it flies), the number world.metrics records for this tick."""
        eng = self._world.engine
        out = {}
        for rid in self._sc.follower_ids:
            x, y = eng.true_target(rid)
            pose = eng.robots[rid].pose
            out[rid] = math.hypot(x - pose.x_m, y - pose.y_m)
        return out

    def _sim_s(self) -> float:
        """What the fault log records as wall time: the sim time (nothing here waits)."""
        return self._world.engine.time_s

    # -- the run ------------------------------------------------------------------------
    def observe(self) -> bool:
        """Run the next tick up to the robots' answers, not yet taken by the
        world: its fault calls, observations and answers (:attr:`inputs`,
        :attr:`wheels`). Whether there is a tick (False once the run has
        ended). Once per tick: observing an open tick again does nothing."""
        world = self._world
        if self._open is not None:
            return True
        if not world.running:
            return False
        t0 = time.perf_counter()
        self._inputs.clear()
        world.start(self._sim_s())
        self._process_faults()
        self._open = self._answers()
        self._wall_s += time.perf_counter() - t0
        return True

    def step(self, actions: Actions | None = None) -> bool:
        """Run one tick (the rest of it, after :meth:`observe`); whether the
        run goes on (False once it has ended: then a step does nothing).
        ``actions``: wheel speeds {robot id: (left_mps, right_mps)}, each
        within robot.max_wheel_mps, in place of those robots' answers this
        tick; a robot that did not answer it (killed, frozen, its observation
        lost) takes none. ValueError for a robot or speeds that are not."""
        given = {} if actions is None else checked_actions(actions, self._sc.robots, self._sc.max_wheel_mps)
        if not self.observe() or self._open is None:
            return False
        world = self._world
        t0 = time.perf_counter()
        (commands, codes), self._open = self._open, None
        for rid, (left, right) in given.items():
            if rid in commands:
                commands[rid] = dataclasses.replace(commands[rid], left_mps=left, right_mps=right)
        world.record()
        for rid, command in commands.items():
            world.receive(rid, command.to_bytes())
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
            agents.close()  # as its processes close theirs when they stop: a close's failure is the run's
            self._result = result(self._sc, stats, agents.stats(), self._events, agents.notes)
        return self._result

    def close(self) -> None:
        """Close the run's controllers and the leader's policy (their ``close()``),
        as the end of ``run()`` and ``reset()`` do; once each. Also ``with Engine(...) as engine``."""
        self._agents.close()

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def _answers(self) -> tuple[dict[int, Command], list[bytes]]:
        """Each observed robot's command to the tick's observation, and the
        leader's code (routed after the step) as bytes."""
        agents, commands, codes = self._agents, {}, []
        for rid, obs in self._world.observations():
            if rid not in agents:  # no agent hears it (none is observed without one in lockstep)
                continue
            answer = agents.answer(rid, obs.to_bytes())
            if answer is None:
                continue
            if answer.code is not None:
                codes.append(answer.code.to_bytes())
            commands[rid] = answer.command
            agents.prepare(rid)
        return commands, codes

    def _process_faults(self) -> None:
        """This tick's fault calls, the world's side and the agents', each an
        event as ``swarm run``'s launcher records it; then the robots whose
        agent is back are re-admitted."""
        world, agents = self._world, self._agents
        for call in world.calls_due():
            if (rid := world.apply_call(call)) is not None:  # a restart's "start": the world waits for it
                self._event("started", self._start(rid), call)
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
