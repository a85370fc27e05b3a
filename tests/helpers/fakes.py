"""Stand-ins for what a role's process hands it: a stop event, a publisher;
and the agent process's loop for one tick, without the process."""

from __future__ import annotations

from formation_swarm.agents.role_base import Answer, RoleBase
from formation_swarm.protocol.messages import WORLD_ID, Observation
from formation_swarm.runtime.proc import StopEvent


class FakeRole:
    """What the roles use of role.Role here: a stop event (and no signal handlers in the test process)."""

    def __init__(self) -> None:
        self.stop = StopEvent()


class FakePub:
    def __init__(self) -> None:
        self.payloads: list[bytes] = []

    def put(self, payload: bytes) -> None:
        self.payloads.append(payload)


def observation(
    tick: int,
    readings: tuple[tuple[int, float, float, float], ...] = (),
    *,
    dt_s: float = 0.05,
    seq: int | None = None,
    pose: tuple[float, float, float] = (0.0, 0.0, 1.57),
    obstacles: tuple[tuple[float, float, float], ...] = (),
) -> Observation:
    """The world's observation of tick ``tick`` (numbered from 1 by default, as the world does)."""
    return Observation(
        sender=WORLD_ID,
        seq=tick + 1 if seq is None else seq,
        tick=tick,
        time_s=tick * dt_s,
        pose=pose,
        readings=readings,
        obstacles=obstacles,
    )


def answer(role: RoleBase, obs: Observation) -> Answer:
    """One pass of the agent's loop (nodes.agent.node): the observation taken,
    answered, then the role prepares for the next tick."""
    role.take_observation(obs)
    got = role.answer()
    if got is None:
        raise AssertionError(f"tick {obs.tick} was not answered: {dict(role.rejections.by_reason)}")
    role.prepare()
    return got
