"""A lockstep run replayed in one process: the world's tick (world.tick) and
every robot's role (agents.leader_role, agents.follower_role, built by
nodes.agent.setup as the agent process builds them), driven the way the
world process (nodes.world.node, nodes.world.clock's LockstepClock) and the
agent processes (nodes.agent.main, nodes.agent.wire) drive them, without Zenoh.

Each message crosses as bytes, as on the wire: an agent's side decodes what
reaches its inbox with the process's own ``nodes.agent.wire.Router``, the world
takes each command's payload with ``WorldTick.receive``. Tick k:

- the fault calls of tick k, the robots whose agent is back (world side; a
  killed agent's role is gone, a restarted robot gets a fresh role);
- the tick's observations, followers first (``WorldTick.observations``):
  each robot's role takes its own, answers it (the code to the followers,
  then the command to the world) and prepares the next tick;
- the world records the last tick's metrics, then takes the commands (a
  robot with none misses the tick, as at the lockstep deadline), closes the
  tick and steps;
- the leader's formation code reaches each follower's inbox before tick
  k + 1's observation (its put precedes the command the world waited for),
  so a follower holds it from k + 1 on, as in lockstep.

In lockstep the processes add nothing to the figures: this gives the run's
trajectory digest bit for bit (tests/system/test_distributed.py checks it
against real runs), and the published figures are recomputed in seconds by
tests/unit/studies/test_published.py and by mutation testing.

What it replays: steady link drops, link faults (drop, burst, delay,
duplicate, reorder, partition: the roles' and the world's receiving ends),
sensor and actuator faults (the world's engine), and the process faults on
agents that the world places on its ticks: kill, restart (the fresh agent
is there at once, as the lockstep world waits for it), freeze. Not what
depends on the processes' timing: a process too slow for the lockstep
deadline, an agent frozen beyond the Zenoh lease (the router drops its
session), a frozen logger holding back the agents' telemetry. There is no
logger here, and no telemetry or ground truth is sent.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.nodes.agent.wire import Router
from formation_swarm.protocol.keys import Keys
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.process_faults import KILL
from formation_swarm.world.tick import WorldTick

RUN_ID = "replica"


def replay(path: str | Path, seed: int, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The world's summary of the lockstep run of a scenario with this seed."""
    replica = Replica(scenario_mod.load(path, overrides), seed)
    replica.run()
    return replica.world.summary()


class Replica:
    """One lockstep run: the world's tick and an agent (its role, behind its inbox) per robot."""

    def __init__(self, sc: scenario_mod.Scenario, seed: int) -> None:
        self.sc = sc
        self.seed = seed
        self.keys = Keys(RUN_ID)
        self.world = WorldTick(sc, seed, lockstep=True, wall_s=self._sim_s)
        self.agents: dict[int, Router] = {}  # the robots whose agent is there, by robot id
        for rid in sc.robots:
            self._start_agent(rid)

    def _sim_s(self) -> float:
        """What the fault log records as wall time: the sim time (nothing here waits)."""
        return self.world.engine.time_s

    def _start_agent(self, rid: int) -> None:
        """A fresh agent for robot ``rid``: its role, and its token the world sees."""
        self.agents[rid] = Router(self.keys, role_for(self.sc, rid, self.seed))
        self.world.agent_token(rid, True)

    def run(self) -> None:
        world, keys = self.world, self.keys
        while world.running:
            world.start(self._sim_s())
            self._process_faults()
            commands: list[tuple[int, bytes]] = []
            codes: list[bytes] = []
            for rid, obs in world.observations():
                agent = self.agents.get(rid)
                if agent is None:  # no agent hears it (none is observed without one in lockstep)
                    continue
                agent.take(keys.obs(rid), obs.to_bytes())
                answer = agent.role.answer()
                if answer is None:
                    continue
                if answer.code is not None:
                    codes.append(answer.code.to_bytes())
                commands.append((rid, answer.command.to_bytes()))
                agent.role.prepare()
            world.record()
            for rid, payload in commands:
                world.receive(rid, payload)
            if waiting := world.waiting():
                world.miss(waiting)  # the lockstep deadline passes: stopped for this step
            world.close()
            world.step()
            for payload in codes:  # the router's copy to every follower's inbox
                for agent in self.agents.values():
                    if agent.role.TAKES_CODES:
                        agent.take(keys.codes, payload)

    def _process_faults(self) -> None:
        """This tick's fault calls, the world's side and the agents': a killed
        agent leaves (its token goes), a restart's "start" brings a fresh one
        (the world waits for it in lockstep), which is re-admitted now."""
        world = self.world
        for call in world.calls_due():
            if (rid := world.apply_call(call)) is not None:
                self._start_agent(rid)
            elif call.action == KILL and call.robot in self.agents:
                del self.agents[call.robot]
                world.agent_token(call.robot, False)
        world.readmit(self.agents.__contains__)
