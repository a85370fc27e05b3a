"""The robots' agents in the engine: each robot's role (built by
nodes.agent.setup as the agent process builds it) behind the process's own
``nodes.agent.wire.Router``, so that every message reaches it as bytes, as
off the wire. A restart stops a robot's agent and starts a fresh one; their
stats are those the agent processes write (nodes.agent.stats), less the
process's own clocks.
"""

from __future__ import annotations

import collections
from collections.abc import Iterable
from typing import Any

from formation_swarm.agents.role_base import Answer
from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.nodes.agent.wire import Router
from formation_swarm.protocol.keys import Keys
from formation_swarm.spec.scenario import Scenario

RUN_ID = "engine"  # the keys' run id: nothing else shares them in one process


class Agents:
    """The agent of each robot that has one, by robot id; the stats of every
    agent the run had, by process name (agent-3, then agent-3.2 after a restart)."""

    def __init__(self, sc: Scenario, seed: int) -> None:
        self.sc = sc
        self.seed = seed
        self.keys = Keys(RUN_ID)
        self.live: dict[int, Router] = {}
        self.names: dict[int, str] = {}  # robot -> its newest agent's name
        self.started: collections.Counter[int] = collections.Counter()
        self.gone: dict[str, dict[str, Any]] = {}  # the stats of the agents stopped, as they stopped
        self.notes: list[str] = []  # what the roles noted (a controller's failure, its traceback), by agent

    def __contains__(self, rid: object) -> bool:
        return rid in self.live

    def start(self, rid: int) -> str:
        """A fresh agent for robot ``rid``; its name."""
        self.started[rid] += 1
        n = self.started[rid]
        self.names[rid] = name = f"agent-{rid}" if n == 1 else f"agent-{rid}.{n}"
        self.live[rid] = Router(self.keys, role_for(self.sc, rid, self.seed))
        return name

    def stop(self, rid: int) -> str:
        """Robot ``rid``'s agent leaves (killed); its name."""
        name = self.names[rid]
        self.gone[name] = _stats(self.live.pop(rid))
        return name

    def answer(self, rid: int, payload: bytes) -> Answer | None:
        """Robot ``rid``'s answer to an observation's payload (None: none)."""
        agent = self.live[rid]
        agent.take(self.keys.obs(rid), payload)
        answer = agent.role.answer()
        if agent.role.notes:
            self.notes += [f"{self.names[rid]}: {note}" for note in agent.role.notes]
            agent.role.notes.clear()
        return answer

    def prepare(self, rid: int) -> None:
        """Robot ``rid``'s role prepares the next tick once its answer is sent."""
        self.live[rid].role.prepare()

    def codes(self, payloads: Iterable[bytes]) -> None:
        """Formation codes, as the router copies them into every follower's inbox."""
        for payload in payloads:
            for agent in self.live.values():
                if agent.role.TAKES_CODES:
                    agent.take(self.keys.codes, payload)

    def close(self) -> None:
        """Every live agent's controller or policy closed, once (agents.hooks):
        as its process closes it when it stops. An agent a fault killed is not
        (a process killed gets no call). What a close raised is among the notes."""
        for rid, agent in self.live.items():
            agent.role.close()
            self.notes += [f"{self.names[rid]}: {note}" for note in agent.role.notes]
            agent.role.notes.clear()

    def stats(self) -> dict[str, dict[str, Any]]:
        """Every agent's stats, by name: the agents stopped, then those still there."""
        return {**self.gone, **{self.names[rid]: _stats(agent) for rid, agent in self.live.items()}}


def _stats(agent: Router) -> dict[str, Any]:
    """An agent's stats as its process writes them (nodes.agent.node), without its clocks."""
    role = agent.role
    return {
        **role.stats(),
        "robot": role.robot_id,
        "role": role.NAME,
        "lockstep": True,
        "rejected": dict(role.rejections.by_reason),
    }
