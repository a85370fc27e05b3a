"""What a follower accepts from the wire, one message at a time and without a
network: its role (formation codes: sender, formation, tick) and the
agent's router in front of it (keys, payloads). Every rejection is counted
by its reason; nothing rejected changes what the robot does."""

from __future__ import annotations

import itertools

import pytest

from formation_swarm.agents.follower_role import FollowerRole
from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.nodes.agent.wire import Router
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Command, FormationCode
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS
from tests.helpers.fakes import answer, observation

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")  # 1 leads; triangle (code 0), line (code 1)
KEYS = Keys("inputs-test")
LINE, TRIANGLE = FIG11.code_of("line"), FIG11.code_of("triangle")


def _follower(rid: int = 2) -> FollowerRole:
    role = role_for(FIG11, rid, FIG11.seed)
    assert isinstance(role, FollowerRole)
    return role


def _observe(role: FollowerRole, tick: int) -> Command:
    return answer(role, observation(tick, ((1, 2.0, 0.0, 0.6),), dt_s=FIG11.dt_s)).command


_SEQ = itertools.count(100)  # a leader's seq only grows (the agent refuses a replayed one)


def _code(role: FollowerRole, sender: int, code: int, tick: int = 0) -> None:
    role.take_code(FormationCode(sender=sender, seq=next(_SEQ), tick=tick, code=code))


def test_a_formation_code_from_the_leader_is_flown_from_the_next_tick() -> None:
    role = _follower()
    _code(role, sender=1, code=LINE, tick=0)
    assert _observe(role, 0).formation == TRIANGLE  # the code answers tick 0: from tick 1 on
    assert _observe(role, 1).formation == LINE
    assert role.rejections.by_reason == {}
    assert role.stats()["formation_changes"] == [{"tick": 0, "code": LINE, "name": "line"}]


@pytest.mark.parametrize("sender", [3, 2])  # the other follower; itself
def test_a_formation_code_from_anyone_but_the_leader_is_rejected(sender: int) -> None:
    role = _follower()
    _code(role, sender=sender, code=LINE)
    assert [_observe(role, k).formation for k in (0, 1, 2)] == [TRIANGLE] * 3
    assert role.rejections.by_reason == {"sender mismatch": 1}


def test_an_unknown_formation_is_rejected_and_counted() -> None:
    role = _follower()
    _code(role, sender=1, code=len(FIG11.formation_names))  # one past the last
    _code(role, sender=1, code=255)
    assert [_observe(role, k).formation for k in (0, 1)] == [TRIANGLE] * 2
    assert role.rejections.by_reason == {"unknown formation": 2}
    assert role.stats()["formation_changes"] == []


def test_what_is_not_for_this_robot_is_rejected_by_reason() -> None:
    role = _follower()
    router = Router(KEYS, role)
    router.take(KEYS.obs(3), b"")  # another robot's key
    router.take("elsewhere/robot/2/obs", b"")
    router.take(KEYS.cmd(2), _observe(_follower(), 0).to_bytes())  # its own output
    router.take(KEYS.obs(2), observation(0).to_bytes()[:-1])  # cut short
    router.take(KEYS.codes, b"\xc1")
    code = FormationCode(sender=1, seq=next(_SEQ), tick=0, code=0).to_bytes()
    router.take(f"{KEYS.prefix}/robot/2/formation", code)  # codes come on the one shared key only
    assert role.rejections.by_reason == {"unknown key": 3, "unexpected key": 1, "not msgpack": 2}
    assert role.answer() is None  # nothing to answer


def test_the_router_hands_the_role_what_decodes() -> None:
    role = _follower()
    router = Router(KEYS, role)
    router.take(KEYS.codes, FormationCode(sender=1, seq=next(_SEQ), tick=0, code=LINE).to_bytes())
    router.take(KEYS.obs(2), observation(0, ((1, 2.0, 0.0, 0.6),)).to_bytes())
    first = role.answer()
    router.take(KEYS.obs(2), observation(1, ((1, 2.0, 0.0, 0.6),)).to_bytes())
    second = role.answer()
    assert first is not None
    assert second is not None
    assert (first.command.formation, second.command.formation) == (TRIANGLE, LINE)
    assert role.rejections.by_reason == {}


def test_a_leader_takes_no_formation_code() -> None:
    leader = role_for(FIG11, 1, FIG11.seed)
    router = Router(KEYS, leader)
    router.take(KEYS.codes, FormationCode(sender=1, seq=next(_SEQ), tick=0, code=LINE).to_bytes())
    router.take(KEYS.codes, b"\xc1")  # not even decoded
    assert leader.rejections.by_reason == {"unexpected key": 2}
