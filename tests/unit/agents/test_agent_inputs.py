"""What the agent accepts from the wire, one message at a time and without a
network: its inbox (formation codes: sender, formation, tick). Every rejection
is counted by its reason; nothing rejected changes what the robot does."""

from __future__ import annotations

import itertools

import pytest

from formation_swarm.nodes.agent import Agent
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Command, FormationCode, Observation
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS
from tests.helpers.fakes import FakePub, FakeRole

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")  # 1 leads; triangle (code 0), line (code 1)
RUN = "inputs-test"
KEYS = Keys(RUN)


def _follower(rid: int = 2) -> tuple[Agent, FakePub]:
    agent = Agent(None, FIG11, rid, RUN, FIG11.seed, FakeRole())  # type: ignore[arg-type]  # no session needed
    cmd = FakePub()
    agent.cmd_pub, agent.tel_pub = cmd, FakePub()
    return agent, cmd


def _observe(agent: Agent, tick: int) -> Command:
    obs = Observation(0, tick + 1, tick, tick * FIG11.dt_s, (0.0, 0.0, 1.57), ((1, 2.0, 0.0, 0.6),), ())
    taken = agent._on_message(KEYS.obs(agent.rid), obs.to_bytes())
    assert taken is not None
    agent._on_observation(*taken)
    return Command.from_bytes(agent.cmd_pub.payloads[-1])


_SEQ = itertools.count(100)  # a leader's seq only grows (the agent refuses a replayed one)


def _code(agent: Agent, sender: int, code: int, tick: int = 0) -> None:
    agent._on_message(KEYS.codes, FormationCode(sender, next(_SEQ), tick, code).to_bytes())


LINE = FIG11.code_of("line")


def test_a_formation_code_from_the_leader_is_flown_from_the_next_tick() -> None:
    agent, _ = _follower()
    _code(agent, sender=1, code=LINE, tick=0)
    assert _observe(agent, 0).formation == FIG11.code_of("triangle")  # the code answers tick 0: from tick 1 on
    assert _observe(agent, 1).formation == LINE
    assert agent.rejections.by_reason == {}


@pytest.mark.parametrize("sender", [3, 2])  # the other follower; itself
def test_a_formation_code_from_anyone_but_the_leader_is_rejected(sender: int) -> None:
    agent, _ = _follower()
    _code(agent, sender=sender, code=LINE)
    assert [_observe(agent, k).formation for k in (0, 1, 2)] == [FIG11.code_of("triangle")] * 3
    assert agent.rejections.by_reason == {"sender mismatch": 1}


def test_an_unknown_formation_is_rejected_and_counted() -> None:
    agent, _ = _follower()
    _code(agent, sender=1, code=len(FIG11.formation_names))  # one past the last
    _code(agent, sender=1, code=255)
    assert [_observe(agent, k).formation for k in (0, 1)] == [FIG11.code_of("triangle")] * 2
    assert agent.rejections.by_reason == {"unknown formation": 2}
    assert agent.stats()["rejected"] == {"unknown formation": 2}


def test_what_is_not_for_this_robot_is_rejected_by_reason() -> None:
    agent, cmd = _follower()
    agent._on_message(KEYS.obs(3), b"")  # another robot's key
    agent._on_message("elsewhere/robot/2/obs", b"")
    agent._on_message(KEYS.cmd(2), Command(2, 1, 0, 0.0, 0.0, 0, False).to_bytes())  # its own output
    agent._on_message(KEYS.obs(2), Observation(0, 1, 0, 0.0, (0.0, 0.0, 0.0), (), ()).to_bytes()[:-1])  # cut short
    agent._on_message(KEYS.codes, b"\xc1")
    code = FormationCode(1, next(_SEQ), 0, 0).to_bytes()
    agent._on_message(f"{KEYS.prefix}/robot/2/formation", code)  # codes come on the one shared key only
    assert agent.rejections.by_reason == {"unknown key": 3, "unexpected key": 1, "not msgpack": 2}
    assert cmd.payloads == []  # nothing answered
