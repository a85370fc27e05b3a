"""``leader.policy`` and ``[leader.params]`` checked when a scenario loads,
as a follower's law and its params are: each error one line naming the key;
the policy named in the run's laws."""

from __future__ import annotations

from typing import Any

import pytest

from formation_swarm.spec import scenario as sm
from formation_swarm.spec.laws import laws, laws_as_run
from tests.helpers import SCENARIOS

FIG11 = SCENARIOS / "fig11_obstacles.toml"
MINE = "tests.helpers.hooked:Leader"

REFUSED: dict[str, tuple[dict[str, Any], str]] = {
    "no such module": (
        {"leader.policy": "no_such_module_xyz:Eight"},
        "leader.policy: cannot import 'no_such_module_xyz' for policy 'no_such_module_xyz:Eight': no module named "
        "'no_such_module_xyz'; is it installed or on PYTHONPATH?",
    ),
    "no such class": (
        {"leader.policy": "tests.helpers.hooked:Leadr"},
        "leader.policy: module 'tests.helpers.hooked' has no class 'Leadr'; did you mean 'Leader'?",
    ),
    "no such entry point": (
        {"leader.policy": "figure_eigth"},
        "leader.policy: no policy named 'figure_eigth': not built in, not module:Class, and no entry point of group "
        "'formation_swarm.leader_policies' has that name",
    ),
    "an unknown param": (
        {"leader.policy": MINE, "leader.params.raise_inn": "close"},
        "unknown key leader.params.raise_inn; did you mean 'raise_in'?",
    ),
    "a param of the wrong type": (
        {"leader.policy": MINE, "leader.params.log": 3},
        "leader.params.log must be a string, got 3",
    ),
    "params for the paper's": (
        {"leader.params.radius_m": 5.0},
        "unknown key leader.params.radius_m: policy 'path' takes no params (its parameters are the keys of [leader])",
    ),
    "a policy that is no string": ({"leader.policy": 3}, "leader.policy must be a string, got 3"),
    "params that are no table": ({"leader.params": [1]}, "leader.params must be a table, got [1]"),
}


@pytest.mark.parametrize("case", REFUSED)
def test_a_policy_that_cannot_be_flown_is_one_line_naming_its_key(case: str) -> None:
    overrides, said = REFUSED[case]
    with pytest.raises(sm.ScenarioError) as err:
        sm.load(FIG11, overrides=overrides)
    text = str(err.value)
    assert "\n" not in text
    assert text.endswith(f": {said}"), text


def test_a_policys_params_are_its_declared_defaults_with_the_scenarios_over_them() -> None:
    sc = sm.load(FIG11, overrides={"leader.policy": MINE, "leader.params.raise_in": "never"})
    assert (sc.leader.policy, sc.leader.policy_params) == (MINE, (("raise_in", "never"), ("log", "")))
    assert laws(sc)["leader"] == MINE
    assert laws_as_run(sc.raw, sc.follower_ids) == laws(sc)  # read from the scenario as run, unchecked
    assert laws_as_run({}, [2])["leader"] == "path"


def test_a_users_policy_keeps_within_the_wheels_itself() -> None:
    """The path follower's fastest wheel (leader.speed_mps + leader.turn_rate_rps * width / 2) is
    checked against robot.max_wheel_mps; a policy of the user's is given max_wheel_mps instead."""
    fast = {"leader.speed_mps": 2.95, "controller.vn": 1.0}
    with pytest.raises(sm.ScenarioError, match="the leader's wheels reach 3.0125 m/s"):
        sm.load(FIG11, overrides=fast)
    with pytest.warns(sm.ScenarioWarning, match="above the speeds followers 2-3' fuzzy controllers hold"):
        assert sm.load(FIG11, overrides={**fast, "leader.policy": MINE}).leader.speed_mps == 2.95
