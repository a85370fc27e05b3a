"""A user's follower controller (docs/controllers.md) without the network: its
law found by module:Class, its parameters checked against what its class
declares, its own values in the telemetry, and what a failing one does to
its robot (it stops, for good) and to the role's stats and notes."""

from __future__ import annotations

import math

import pytest

from formation_swarm import ControllerSetup, FollowerOutput
from formation_swarm.agents.follower import FuzzyController, make_controller
from formation_swarm.agents.follower_role import FollowerRole
from formation_swarm.agents.laws import LawError, declared_params, find_class
from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.protocol.messages import MAX_EXTRAS, Telemetry
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS
from tests.helpers.controllers import LAW, Paper
from tests.helpers.fakes import answer, observation

FIG11 = SCENARIOS / "fig11_obstacles.toml"
READING = (1, 2.0, 0.0, -0.6)  # robot 2 sees the leader's marker


def _load(**overrides: object) -> scenario_mod.Scenario:
    return scenario_mod.load(FIG11, overrides=overrides)


def _role(sc: scenario_mod.Scenario, rid: int = 2) -> FollowerRole:
    role = role_for(sc, rid, sc.seed)
    assert isinstance(role, FollowerRole)
    return role


def _fly(role: FollowerRole, ticks: range) -> list:
    return [answer(role, observation(k, (READING, (3, 1.0, 0.0, 0.0)))) for k in ticks]


# -- the law and its parameters ------------------------------------------------------


def test_a_law_by_module_and_class_gets_its_declared_parameters_with_the_scenarios_over_them() -> None:
    sc = _load(**{"controller.law": f"{LAW}:Paper", "controller.params": {"scale": 2, "note": "x"}})
    assert sc.followers[2].law == f"{LAW}:Paper"
    # Every declared parameter, each given or its default; an integer given for a float: the float.
    assert dict(sc.followers[2].law_params) == {**Paper.PARAMS, "scale": 2.0, "note": "x"}
    role = _role(sc)
    assert isinstance(role.controller, Paper)
    assert role.controller.params == {**Paper.PARAMS, "scale": 2.0, "note": "x"}
    assert type(role.controller.params["scale"]) is float


def test_a_followers_params_go_over_the_controllers_name_by_name_unless_it_flies_another_law() -> None:
    sc = scenario_mod.from_dict(
        {
            **scenario_mod.load(FIG11).raw,
            "controller": {"law": f"{LAW}:Paper", "params": {"scale": 0.5, "loud": True}},
            "followers": {"2": {"params": {"scale": 0.75}}, "3": {"law": "fuzzy"}},
        }
    )
    assert dict(sc.followers[2].law_params) == {**Paper.PARAMS, "scale": 0.75, "loud": True}
    assert (sc.followers[3].law, sc.followers[3].law_params) == ("fuzzy", ())


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"controller.law": "no_such_module_xyz:Ctl"}, "cannot import 'no_such_module_xyz' for law"),
        ({"controller.law": f"{LAW}:Papr"}, f"module '{LAW}' has no class 'Papr'; did you mean 'Paper'?"),
        ({"controller.law": f"{LAW}:NoStep"}, f"class NoStep of law '{LAW}:NoStep' has no step method"),
        ({"controller.law": f"{LAW}:Paper", "controller.params.scael": 2.0}, "did you mean 'scale'?"),
        ({"controller.law": f"{LAW}:Paper", "controller.params.scale": "big"}, "params.scale must be a number"),
        ({"controller.law": f"{LAW}:Paper", "controller.params.loud": 1}, "params.loud must be true or false"),
        ({"controller.params.gain": 1.0}, "unknown key controller.params.gain: law 'fuzzy' takes no params"),
        ({"controller.law": "no_such_entry_point"}, "no law named 'no_such_entry_point'"),
    ],
)
def test_a_law_that_cannot_be_flown_is_a_scenario_error_of_one_line(overrides: dict, message: str) -> None:
    with pytest.raises(scenario_mod.ScenarioError) as info:
        _load(**overrides)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_a_class_declares_its_parameters_in_params() -> None:
    assert declared_params(find_class(f"{LAW}:Paper")) == Paper.PARAMS
    assert declared_params(FuzzyController) == {}

    class Bad:
        PARAMS = {"gain": [1, 2]}

        def step(self, inp: object) -> None: ...

    with pytest.raises(LawError, match=r"Bad.PARAMS\['gain'\]: a default must be"):
        declared_params(Bad)


def test_make_controller_builds_a_users_class_with_its_setup() -> None:
    sc = _load(**{"controller.law": f"{LAW}:Paper"})
    slot = sc.formations["triangle"].slots[3]
    setup = ControllerSetup(robot_id=3, params=sc.followers[3], slot=slot, max_wheel_mps=2.5, law_params={"scale": 3.0})
    made = make_controller(setup)
    assert isinstance(made, Paper)
    assert made.params["scale"] == 3.0
    assert made.params["fail_at_step"] == -1


def test_a_controllers_wheel_limit_is_its_robots() -> None:
    role = _role(_load(**{"controller.law": f"{LAW}:Chatty", "robot.max_wheel_mps": 2.0}))
    assert role.controller.setup.max_wheel_mps == 2.0
    slot = _load().formations["triangle"].slots[2]
    with pytest.raises(TypeError, match="max_wheel_mps"):
        ControllerSetup(robot_id=2, params=_load().followers[2], slot=slot)  # type: ignore[call-arg]
    with pytest.raises(ValueError, match="max_wheel_mps must be finite, got inf"):
        ControllerSetup(robot_id=2, params=_load().followers[2], slot=slot, max_wheel_mps=math.inf)


# -- what the role does with it ------------------------------------------------------


def test_a_controllers_own_values_travel_as_telemetry_extras() -> None:
    role = _role(_load(**{"controller.law": f"{LAW}:Paper", "controller.params.scale": 0.5}))
    tel = _fly(role, range(3))[-1].telemetry
    assert tel is not None
    assert tel.extras == (("steps", 3.0), ("scale", 0.5))
    assert Telemetry.from_bytes(tel.to_bytes()) == tel
    assert role.notes == []


def test_the_paper_controllers_telemetry_has_no_extras_and_leaves_the_field_off_the_wire() -> None:
    tel = _fly(_role(_load()), range(3))[-1].telemetry
    assert tel is not None
    assert tel.extras == ()
    import msgpack

    assert len(msgpack.unpackb(tel.to_bytes())) == 2 + len(Telemetry._names()) - 1


def test_extras_that_do_not_fit_the_wire_are_left_out_and_said_once() -> None:
    role = _role(_load(**{"controller.law": f"{LAW}:Chatty"}))
    for tel in (a.telemetry for a in _fly(role, range(2))):
        assert tel is not None
        # v0 is NaN this tick: left out, not counted; the first 16 others go.
        assert tel.extras == tuple((f"v{i}", float(i)) for i in range(1, MAX_EXTRAS + 1))
        assert tel.rho_m == 0.5
    unsent = [n.split("'")[1] for n in role.notes]
    assert unsent == ["v17", "v18", "v19", "bad name"]  # each once, not once per tick


def _failing_role(**params: object) -> FollowerRole:
    overrides = {"controller.law": f"{LAW}:Paper", **{f"controller.params.{k}": v for k, v in params.items()}}
    return _role(_load(**overrides))


@pytest.mark.parametrize(
    ("params", "error"),
    [
        ({"fail_at_step": 100}, "RuntimeError: failing on purpose at step 100"),
        ({"nan_at_step": 100}, "ValueError: wheel speeds must be finite numbers, got left_mps=nan"),
    ],
)
def test_a_controller_that_raises_or_gives_nan_stops_its_robot_for_good(params: dict, error: str) -> None:
    role = _failing_role(**params)
    answers = _fly(role, range(110))
    assert [a.command.tick for a in answers] == list(range(110))  # every tick still answered
    moving = [(a.command.left_mps, a.command.right_mps) != (0.0, 0.0) for a in answers]
    assert any(moving[:100])
    assert not any(moving[100:])
    assert role.controller.steps == 101  # never called after it failed
    assert role.failure == {"tick": 100, "error": role.failure["error"], "law": f"{LAW}:Paper"}
    assert role.failure["error"].startswith(error)
    assert role.stats()["controller_failure"] == role.failure
    assert len(role.notes) == 1
    assert role.notes[0].startswith(f"controller {LAW}:Paper failed at tick 100: {error}")
    assert "Traceback (most recent call last)" in role.notes[0]
    stopped = answers[-1].telemetry
    assert stopped is not None
    assert (stopped.rho_m, stopped.estimate, stopped.extras, stopped.left_mps) == (None, None, (), 0.0)


def test_a_controller_whose_class_raises_when_built_fails_at_the_first_tick() -> None:
    role = _role(_load(**{"controller.law": f"{LAW}:BadInit"}))
    answers = _fly(role, range(3))
    assert {(a.command.left_mps, a.command.right_mps) for a in answers} == {(0.0, 0.0)}
    assert role.failure is not None
    assert (role.failure["tick"], role.failure["error"]) == (0, "ValueError: robot 2 cannot be built")
    assert "in __init__" in role.notes[0]  # the traceback of the constructor


@pytest.mark.parametrize(
    ("out", "error"),
    [
        (FollowerOutput(left_mps=0.1, right_mps=0.1, values={"rho_m": "far"}), "ValueError: could not convert"),  # type: ignore[dict-item]
        (FollowerOutput(left_mps=0.1, right_mps=0.1, stop=1), "TypeError: stop must be a string or None, got int 1"),  # type: ignore[arg-type]
    ],
)
def test_non_numbers_in_the_values_or_a_stop_that_is_no_word_are_the_controllers_failure(
    out: FollowerOutput, error: str
) -> None:
    class Odd:
        def step(self, inp: object) -> FollowerOutput:
            return out

    sc = _load()
    role = role_for(sc, 2, sc.seed, Odd())  # type: ignore[arg-type]
    assert isinstance(role, FollowerRole)
    answers = _fly(role, range(2))
    assert role.failure is not None
    assert role.failure["error"].startswith(error)
    assert role.failure["tick"] == 0
    assert [(a.command.left_mps, a.command.right_mps) for a in answers] == [(0.0, 0.0)] * 2
