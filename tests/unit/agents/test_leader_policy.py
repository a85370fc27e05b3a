"""The leader's policy (agents.leader_policy) and the hooks of a policy and a
follower's controller (agents.hooks), driven through their roles without
Zenoh: the policy the scenario names built with its params, reset once
before its first step, closed once; a policy that raises, answers a speed
that is no number or a formation the run does not have, stops the leader
and is recorded as a controller failure, a close that raises too."""

from __future__ import annotations

import math
import re
from typing import Any

import pytest

from formation_swarm.agents.follower_role import FollowerRole
from formation_swarm.agents.laws import LEADER, LawError, find_class
from formation_swarm.agents.leader_policy import BUILT_IN, LeaderMove, PathLeader, make_policy, policy_class
from formation_swarm.agents.leader_role import LeaderRole
from formation_swarm.nodes.agent.setup import leader_setup, role_for
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS, hooked
from tests.helpers.fakes import answer, observation

FIG11 = SCENARIOS / "fig11_obstacles.toml"  # 1 leads 2 and 3; triangle (code 0), line (code 1)
LEADER_CLASS = f"{hooked.MODULE}:Leader"
FOLLOWER_CLASS = f"{hooked.MODULE}:Follower"


def _load(**overrides: Any) -> scenario_mod.Scenario:
    return scenario_mod.load(FIG11, overrides=overrides)


def _fly(role: LeaderRole | FollowerRole, ticks: int) -> list:
    return [answer(role, observation(k, pose=(0.0, 0.075 * k, math.pi / 2))) for k in range(ticks)]


def test_the_default_policy_is_the_papers_path_leader_by_its_short_name() -> None:
    sc = _load()
    assert (sc.leader.policy, sc.leader.policy_params, BUILT_IN) == ("path", (), {"path": PathLeader})
    role = role_for(sc, 1, sc.seed)
    assert isinstance(role, LeaderRole)
    assert type(role.policy) is PathLeader
    assert role.law == "path"


def test_a_policy_is_built_from_its_setup_with_its_params_declared_then_given() -> None:
    sc = _load(**{"leader.policy": LEADER_CLASS, "leader.params.log": "x.log"})
    assert sc.leader.policy_params == (("log", "x.log"), ("raise_in", ""))  # each declared one, filled
    policy = make_policy(leader_setup(sc, 7))
    assert isinstance(policy, hooked.Leader)
    assert (policy.log, policy.raise_in, policy.robot_id) == ("x.log", "", 1)
    setup = leader_setup(sc, 7)
    assert (setup.formations, setup.formation, setup.avoid_formation) == (("triangle", "line"), 0, 1)
    assert (setup.seed, setup.dt_s, setup.width_m, setup.max_wheel_mps) == (7, 0.05, 0.5, 3.0)
    assert setup.params.waypoints == ((0.0, 0.0), (0.0, 80.0))


def test_a_policys_class_is_found_as_a_followers_law_is() -> None:
    assert policy_class(LEADER_CLASS) is hooked.Leader
    with pytest.raises(LawError) as err:
        find_class(f"{hooked.MODULE}:Leadr", LEADER)
    assert re.findall(r"'([^']*)'", str(err.value)) == [hooked.MODULE, "Leadr", "Leader"]  # where, what, the near one
    with pytest.raises(LawError) as err:
        find_class("tests.helpers.controllers:NoStep", LEADER)
    said = str(err.value)
    assert re.findall(r"class (\w+) of (\w+) '([^']+)'", said) == [
        ("NoStep", "policy", "tests.helpers.controllers:NoStep")
    ]
    assert "needs step(LeaderSensing | None) -> LeaderMove" in said  # a leader's step, not a follower's


def test_reset_is_called_once_before_the_first_step_and_close_once() -> None:
    hooked.MADE.clear()
    sc = _load(**{"leader.policy": LEADER_CLASS, "controller.law": FOLLOWER_CLASS})
    roles = [role_for(sc, rid, sc.seed) for rid in sc.robots]
    assert [dict(m.calls) for m in hooked.MADE] == [{"reset": 1}] * 3  # built and reset, not stepped
    for role in roles:
        _fly(role, 5)
        role.close()
        role.close()  # once only
    assert [dict(m.calls) for m in hooked.MADE] == [{"reset": 1, "step": 5, "close": 1}] * 3
    assert [r.stats()["controller_failure"] for r in roles] == [None] * 3


def test_a_close_that_raises_is_a_failure_after_the_last_tick_and_a_note() -> None:
    sc = _load(**{"leader.policy": LEADER_CLASS, "leader.params.raise_in": "close"})
    role = role_for(sc, 1, sc.seed)
    assert isinstance(role, LeaderRole)
    _fly(role, 3)
    role.close()  # no exception: the failure is recorded
    error = "close() raised RuntimeError: close failing on purpose"
    assert role.stats()["controller_failure"] == {"tick": 2, "error": error, "law": LEADER_CLASS}
    (note,) = role.notes
    assert note.startswith(f"controller {LEADER_CLASS} failed after tick 2: {error}\nTraceback")


def test_a_reset_that_raises_fails_the_robot_at_its_first_tick() -> None:
    sc = _load(**{"controller.law": FOLLOWER_CLASS, "followers.3.params.raise_in": "reset"})
    two, three = role_for(sc, 2, sc.seed), role_for(sc, 3, sc.seed)
    _fly(two, 2)
    out = _fly(three, 2)
    assert two.stats()["controller_failure"] is None
    error = "RuntimeError: reset failing on purpose"
    assert three.stats()["controller_failure"] == {"tick": 0, "error": error, "law": FOLLOWER_CLASS}
    assert [(a.command.left_mps, a.command.right_mps) for a in out] == [(0.0, 0.0)] * 2


class _Bad(PathLeader):
    """The paper's leader, its move spoiled from tick 2 on by ``spoil``."""

    spoil: dict[str, Any] = {}

    def step(self, sensed: Any) -> LeaderMove:
        move = super().step(sensed)
        self.steps = getattr(self, "steps", 0) + 1
        if self.steps < 3:
            return move
        if "raise" in self.spoil:
            raise RuntimeError("policy failing on purpose")
        return LeaderMove(**{**{f: getattr(move, f) for f in move.__slots__}, **self.spoil})


@pytest.mark.parametrize(
    ("spoil", "error"),
    [
        ({"raise": True}, "RuntimeError: policy failing on purpose"),
        ({"left_mps": math.nan}, "ValueError: wheel speeds must be finite numbers, got left_mps=nan, right_mps=1.5"),
        ({"formation": 2}, "ValueError: formation must be a code in [0, 1], got 2"),
        ({"formation": True}, "ValueError: formation must be a code in [0, 1], got True"),
    ],
)
def test_a_policy_that_fails_stops_the_leader_and_sends_no_code(
    spoil: dict[str, Any], error: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    sc = _load()
    monkeypatch.setattr(_Bad, "spoil", spoil)
    role = role_for(sc, 1, sc.seed)
    assert isinstance(role, LeaderRole)
    role.policy = _Bad(leader_setup(sc, sc.seed))
    role.law = "bad"
    out = _fly(role, 6)
    assert [a.command.left_mps for a in out] == pytest.approx([1.5, 1.5, 0.0, 0.0, 0.0, 0.0])
    assert [a.code is not None for a in out] == [True, True, False, False, False, False]
    assert {a.command.formation for a in out} == {0}
    assert role.stats()["controller_failure"] == {"tick": 2, "error": error, "law": "bad"}
    assert role.notes[0].startswith(f"controller bad failed at tick 2: {error}; robot 1 stops for the rest of the run")
    assert role.policy.steps == 3  # never called again
