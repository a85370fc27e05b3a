"""The name of each follower's law and of the leader's policy (spec.laws):
from the checked scenario, from the scenario as run, and in summary.json."""

from __future__ import annotations

import json
import tomllib
from typing import Any

import pytest

from formation_swarm.runtime import summary as summary_mod
from formation_swarm.spec import scenario as sm
from formation_swarm.spec.files import shipped
from formation_swarm.spec.laws import LEADER_POLICY, law_name, laws, laws_as_run, run_laws
from tests.helpers.controllers import LAW

MINE = f"{LAW}:Paper"
# fig11_obstacles: R1 leads R2 and R3. Each case: the overrides, then each follower's law by name.
CASES: dict[str, tuple[dict[str, Any], dict[str, str]]] = {
    "as shipped": ({}, {"2": "fuzzy (V_N dynamic)", "3": "fuzzy (V_N dynamic)"}),
    "a static V_N": ({"controller.vn": 1.5}, {"2": "fuzzy (V_N 1.5 m/s)", "3": "fuzzy (V_N 1.5 m/s)"}),
    "a whole number": ({"controller.vn": 2}, {"2": "fuzzy (V_N 2 m/s)", "3": "fuzzy (V_N 2 m/s)"}),
    "l-psi": ({"controller.law": "lpsi"}, {"2": "lpsi", "3": "lpsi"}),
    "a user's law": ({"controller.law": MINE}, {"2": MINE, "3": MINE}),
    "one follower's own": ({"followers.3.law": MINE}, {"2": "fuzzy (V_N dynamic)", "3": MINE}),
    "its own V_N": ({"followers.2.vn": 1.0}, {"2": "fuzzy (V_N 1 m/s)", "3": "fuzzy (V_N dynamic)"}),
    "back to the paper's": (
        {"controller.law": "lpsi", "followers.2.law": "fuzzy"},
        {"2": "fuzzy (V_N dynamic)", "3": "lpsi"},
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_each_follower_is_named_by_its_own_law(case: str) -> None:
    overrides, named = CASES[case]
    sc = sm.load("fig11_obstacles", overrides=overrides)
    assert laws(sc) == {"leader": LEADER_POLICY, "followers": named}
    # Read from the scenario as run, unchecked (a user's law named, not imported): the same.
    assert laws_as_run(sc.raw, sc.follower_ids) == laws(sc)


def test_a_law_is_named_as_the_scenario_names_it_the_fuzzy_one_with_its_vn() -> None:
    got = {law: law_name(law, vn) for law, vn in (("lpsi", 1.5), (MINE, "dynamic"), ("an_entry_point", 2.0))}
    assert got == {"lpsi": "lpsi", MINE: MINE, "an_entry_point": "an_entry_point"}  # V_N is the fuzzy law's
    assert LEADER_POLICY == "path"


def test_every_shipped_scenario_names_every_follower() -> None:
    for name, path in shipped().items():
        sc = sm.load(path)
        named = laws(sc)["followers"]
        assert sorted(map(int, named)) == sorted(sc.follower_ids), name
        assert laws_as_run(tomllib.loads(path.read_text()), sc.follower_ids) == laws(sc), name


def test_a_run_takes_its_summarys_laws_else_its_scenarios() -> None:
    sc = sm.load("fig11_obstacles", overrides={"followers.3.law": "lpsi"})
    said = {"leader": "path", "followers": {"2": MINE, "3": "lpsi"}}
    assert run_laws({"laws": said}, sc.raw, sc.follower_ids) == said
    assert run_laws({}, sc.raw, sc.follower_ids) == laws(sc)  # a summary from before it had laws
    assert run_laws({"laws": "garbled"}, {}, [2])["followers"] == {"2": "fuzzy (V_N dynamic)"}


def test_the_summary_names_the_laws_flown() -> None:
    sc = sm.load("fig11_obstacles", overrides={"controller.vn": 1.5, "followers.3.law": MINE})
    s = summary_mod.build(
        run_id="r1",
        sc=sc,
        mode="lockstep",
        parts={},
        processes={},
        events=[],
        recording=None,
        exit_code=1,
        end_reason=summary_mod.START_FAILED,
        ended_at_s=None,
        interrupted=False,
        timed_out=False,
    )
    assert json.loads(json.dumps(s))["laws"] == {"leader": "path", "followers": {"2": "fuzzy (V_N 1.5 m/s)", "3": MINE}}
