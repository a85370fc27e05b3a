"""What the leader's and a follower's roles share.

A role is the robot's decisions as a plain object, with no Zenoh inside:
decoded messages in (``take_observation``, a follower's ``take_code``),
what to send out (``answer``: an :class:`Answer`). Its process
(formation_swarm.nodes.agent.node) decodes what arrives, hands it over, and
publishes what the role returns, so the role runs under a test exactly as
in its process. agents.leader_role and agents.follower_role are the two.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from formation_swarm.agents import hooks
from formation_swarm.agents.formation import Formation
from formation_swarm.agents.inbox import InboxChecks, ObservationInbox
from formation_swarm.agents.step_times import StepTimes
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.links import Link
from formation_swarm.protocol.messages import Command, FormationCode, Observation, Telemetry


@dataclass(frozen=True, kw_only=True, slots=True)
class Answer:
    """What a role sends for one tick, in this order: the code (to every
    follower, before the command lets the world go on), the command (to the
    world), the telemetry (to the logger)."""

    command: Command
    code: FormationCode | None = None
    telemetry: Telemetry | None = None


@dataclass(frozen=True, kw_only=True)
class RoleSetup:
    """What either role is built from: the run's facts and its receiving ends."""

    robot_id: int
    leader_id: int
    formations: Sequence[Formation]  # by formation code
    code: int  # the formation the run starts in
    dt_s: float
    obs_link: Link[Observation]  # world -> this robot, with the run's faults on it
    checks: InboxChecks


class RoleBase:
    """The counters and the inbox of a role; a subclass answers."""

    NAME: ClassVar[str]
    TAKES_CODES: ClassVar[bool] = False  # formation codes are among its inputs
    SENDS_CODES: ClassVar[bool] = False  # it publishes formation codes
    SENDS_TELEMETRY: ClassVar[bool] = False  # it sends telemetry to the logger

    def __init__(self, setup: RoleSetup) -> None:
        self.robot_id = setup.robot_id
        self.formations = tuple(setup.formations)
        self.code = setup.code
        self.rejections = Rejections()
        self.inbox = ObservationInbox(setup.obs_link, setup.checks, self.rejections)
        self.seq = 0  # the robot's one counter: commands, codes, telemetry
        self.answered = 0
        self.last_tick: int | None = None  # of the newest observation answered
        self.notes: list[str] = []  # lines for the process's log, taken by it (a role does no I/O)
        self.step_times = StepTimes(setup.dt_s)  # its controller's or policy's steps

    @property
    def links(self) -> tuple[Link[Any], ...]:
        """The receiving ends of this robot's links."""
        return (self.inbox.link,)

    def take_observation(self, obs: Observation) -> None:
        """An observation that arrived: checked, kept for the next answer."""
        self.inbox.take(obs)

    def take_code(self, fc: FormationCode) -> None:
        """A formation code that arrived: not an input of this role (see TAKES_CODES)."""
        self.rejections.reject("unexpected key")

    def answer(self) -> Answer | None:
        """What to send for the newest observation taken since the last answer
        (None: none was taken)."""
        raise NotImplementedError

    def prepare(self) -> None:
        """Called once the answer is sent, while the robot waits for its next observation."""

    def _hooked(self, stepper: Any, law: str | None) -> None:
        """What decides the role's steps (a controller, a policy): its name, for a
        failure's report, no failure yet, and its optional ``close()`` (agents.hooks)."""
        cls = type(stepper)
        self.law = law or f"{cls.__module__}:{cls.__qualname__}"
        self.failure: dict[str, Any] | None = None  # tick, error, law
        self._close = hooks.bound(stepper, "close")
        self._closed = False

    def close(self) -> None:
        """Called once when the agent stops: the controller's or policy's ``close()``,
        once, even after a failure; what it raises is its failure, unless it failed before."""
        if not self._closed:
            self._closed = True
            if (failed := hooks.close(self._close, self.law, self.last_tick or 0)) is not None:
                self.failure = self.failure or failed[0]
                self.notes.append(failed[1])

    def describe(self) -> str:
        return self.NAME

    def stats(self) -> dict[str, Any]:
        """The role's counters, for the agent's stats file."""
        return {
            "answered": self.answered,
            "last_tick": self.last_tick,
            "superseded": self.inbox.superseded,
            "formation": self.formations[self.code].name,
            "links": {lk.name: lk.stats() for lk in self.links},
            "step_time": self.step_times.stats(),
        }

    def _next_seq(self) -> int:
        self.seq += 1
        return self.seq

    def _answered(self, tick: int) -> None:
        self.answered += 1
        self.last_tick = tick
