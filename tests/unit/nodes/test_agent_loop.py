"""The agent process's loop (nodes.agent.node.Agent._serve) over a stand-in
for its Zenoh inbox: what it takes and answers around the run's end."""

from __future__ import annotations

import collections
from typing import Any

import zenoh

from formation_swarm.agents.role_base import Answer
from formation_swarm.nodes.agent.node import Agent, Options
from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import FormationCode
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS
from tests.helpers.fakes import FakeRole, observation

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")  # 1 leads, 2 and 3 follow
RUN = "loop-test"


class Say(FakeRole):
    def __init__(self) -> None:
        super().__init__()
        self.said: list[str] = []

    def say(self, text: str) -> None:
        self.said.append(text)

    complain = say


class Payload:
    def __init__(self, data: bytes) -> None:
        self.data = data

    def to_bytes(self) -> bytes:
        return self.data


class Sample:
    def __init__(self, key: str, payload: bytes) -> None:
        self.key_expr = key
        self.payload = Payload(payload)


class Channel:
    """A Zenoh FIFO channel as the loop sees it: once closed, it hands over
    what it holds, then raises."""

    def __init__(self) -> None:
        self.queue: collections.deque[Sample] = collections.deque()
        self.closed = False

    def push(self, key: str, payload: bytes) -> None:
        self.queue.append(Sample(key, payload))

    def try_recv(self) -> Sample | None:
        if self.queue:
            return self.queue.popleft()
        if self.closed:
            raise zenoh.ZError("closed")
        return None

    def recv(self) -> Sample:
        got = self.try_recv()
        assert got is not None, "the loop waits on an open, empty inbox: the test would hang"
        return got

    def undeclare(self) -> None:
        self.closed = True


class LastTick:
    """The outbox of the run's last tick: while the follower answers it, the
    leader's code of that tick reaches its inbox, then the world's "done"
    (its status callback: done, then the inbox closed)."""

    def __init__(self, agent: Agent, channel: Channel, code: FormationCode) -> None:
        self.agent, self.channel, self.code = agent, channel, code
        self.sent: list[Answer] = []

    def send(self, answer: Answer) -> None:
        self.sent.append(answer)
        self.channel.push(self.agent.keys.codes, self.code.to_bytes())
        self.agent.done = True
        self.agent._close_inbox()


def test_a_code_queued_before_the_runs_end_is_counted_not_answered() -> None:
    role = Say()
    agent = Agent(None, FIG11, role_for(FIG11, 2, FIG11.seed), role, Options(run_id=RUN))  # type: ignore[arg-type]
    channel = Channel()
    agent.inbox = channel  # type: ignore[assignment]
    last = 7
    channel.push(Keys(RUN).obs(2), observation(last, dt_s=FIG11.dt_s).to_bytes())
    code = FormationCode(sender=1, seq=1, tick=last, code=FIG11.code_of("line"))
    outbox = LastTick(agent, channel, code)

    agent._serve(channel, outbox)  # type: ignore[arg-type]

    assert [a.command.tick for a in outbox.sent] == [last]  # the code after "done" gets no answer
    codes = next(lk for lk in agent.brain.links if lk.name.startswith("formation:"))
    assert codes.stats()["received"] == 1
    assert agent.brain.rejections.total == 0
    assert not channel.queue


def test_the_loop_ends_on_a_closed_inbox_without_done() -> None:
    """The world gone (its token lost for good): the inbox closed, nothing queued."""
    role = Say()
    agent = Agent(None, FIG11, role_for(FIG11, 2, FIG11.seed), role, Options(run_id=RUN))  # type: ignore[arg-type]
    channel = Channel()
    channel.closed = True
    sent: list[Any] = []

    class Outbox:
        send = sent.append

    agent._serve(channel, Outbox())  # type: ignore[arg-type]
    assert sent == []
    assert (agent.done, agent.started) == (False, False)
