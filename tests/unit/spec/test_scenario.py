"""Scenario files: the shipped ones load; bad keys and values fail with the key's name."""

from __future__ import annotations

from pathlib import Path

import pytest

from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as sm
from formation_swarm.spec.keys import MAX_OBSTACLES, MAX_ROBOTS
from formation_swarm.spec.keys_doc import markdown
from tests.helpers import ROOT, SCENARIOS

FIG11 = SCENARIOS / "fig11_obstacles.toml"


@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.toml")), ids=lambda p: p.stem)
def test_every_shipped_scenario_loads(path: Path) -> None:
    sc = sm.load(path)
    assert sc.ticks > 0
    assert sc.leader.robot_id in sc.robots
    assert set(sc.follower_ids) == set(sc.robots) - {sc.leader.robot_id}


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"run.dt": 0.1}, "unknown key run.dt; did you mean 'dt_s'?"),
        ({"leader.sped_mps": 1.0}, "unknown key leader.sped_mps; did you mean 'speed_mps'?"),
        ({"controller.gama_deg": 1.0}, "unknown key controller.gama_deg; did you mean 'gamma_deg'?"),
        ({"linkz": {}}, "unknown section [linkz]; did you mean 'links'?"),
        ({"robots": 30}, "unknown section [robots]; did you mean 'run.robots'?"),  # a key without its section
        ({"seed": 3}, "unknown section [seed]; did you mean 'run.seed'?"),
        ({"links.obs_drop": 1.5}, "links.obs_drop must be in [0, 1], got 1.5"),
        ({"run.dt_s": -0.05}, "run.dt_s must be > 0, got -0.05"),
        ({"run.dt_s": "fast"}, "run.dt_s must be"),
        ({"run.robots": 1}, f"run.robots must be in [2, {MAX_ROBOTS}], got 1"),
        ({"run.robots": MAX_ROBOTS + 1}, f"run.robots must be in [2, {MAX_ROBOTS}]"),
        (
            {"obstacles": [{"x_m": 0.0, "y_m": 0.0, "radius_m": 1.0}] * (MAX_OBSTACLES + 1)},
            f"at most {MAX_OBSTACLES} obstacles, got {MAX_OBSTACLES + 1}",
        ),
        ({"obstacles": [{"x_m": 0.0, "y_m": 0.0, "radius": 1.0}]}, "did you mean 'radius_m'?"),
        ({"obstacles": [{"x_m": 0.0, "y_m": 0.0, "radius_m": 0.0}]}, "obstacles[0].radius_m must be > 0, got 0.0"),
        ({"run.seed": -3}, "run.seed must be in [0, 2**63 - 1], got -3"),
        ({"camera.fov_deg": 400.0}, "camera.fov_deg must be in (0, 360], got 400.0"),
        ({"leader.code_burst_s": -1}, "leader.code_burst_s must be >= 0, got -1"),
        ({"controller.ekf": {"q_pos": 1.0}}, "unknown key controller.ekf.q_pos; did you mean 'q_pos_m'?"),
        ({"controller.use_ekf": 1}, "controller.use_ekf must be true or false, got 1"),
        ({"controller.lookahead_m": True}, "controller.lookahead_m must be a number, got true"),
        ({"controller.hold_speed_mps": -0.1}, "controller.hold_speed_mps must be >= 0, got -0.1"),
        ({"controller.hold_after_s": 0}, "controller.hold_after_s must be > 0, got 0"),
        (
            {"controller.resume_speed_mps": 0.05},
            "controller: resume_speed_mps must be >= hold_speed_mps (0.1), got 0.05",
        ),
    ],
)
def test_bad_keys_and_values_name_the_key(overrides: dict, message: str) -> None:
    with pytest.raises(sm.ScenarioError) as info:
        sm.load(FIG11, overrides=overrides)
    assert message in str(info.value)
    assert str(FIG11) in str(info.value)  # and the file


def test_missing_file_and_bad_toml_are_clear(tmp_path: Path) -> None:
    with pytest.raises(sm.ScenarioError, match="scenario file not found"):
        sm.load(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[run\nrobots = 3\n")
    with pytest.raises(sm.ScenarioError, match="not valid TOML"):
        sm.load(bad)


def test_a_shipped_scenario_loads_by_name_and_a_near_miss_is_suggested() -> None:
    assert set(scenario_files.shipped()) == {p.stem for p in SCENARIOS.glob("*.toml")}
    assert sm.load("fig11_obstacles").name == sm.load(FIG11).name == "fig11-obstacles"
    with pytest.raises(sm.ScenarioError, match="named 'fig11_obstacle'; did you mean 'fig11_obstacles'"):
        sm.load("fig11_obstacle")
    assert all(scenario_files.description(p) for p in scenario_files.shipped().values())


def test_command_line_values_parse_as_toml_or_text() -> None:
    assert scenario_files.parse_override("leader.speed_mps=1.6") == ("leader.speed_mps", 1.6)
    assert scenario_files.parse_override("leader.waypoints=[[0, 0], [0, 9.5]]") == (
        "leader.waypoints",
        [[0, 0], [0, 9.5]],
    )
    assert scenario_files.parse_override("controller.vn = dynamic") == ("controller.vn", "dynamic")
    with pytest.raises(sm.ScenarioError, match="KEY=VALUE"):
        scenario_files.parse_override("leader.speed_mps")


def test_docs_scenario_md_is_generated_from_the_schema() -> None:
    doc = (ROOT / "docs" / "scenario.md").read_text()
    assert doc == markdown(), "docs/scenario.md is stale: run make docs"
    # every key the loader accepts in a shipped scenario appears in the document
    for path in SCENARIOS.glob("*.toml"):
        for section, table in sm.load(path).raw.items():
            keys = table.keys() if isinstance(table, dict) else {k for item in table for k in item}
            for key in keys:
                if section not in ("formations", "followers"):
                    assert f"| `{key}` |" in doc, f"{section}.{key}"


def test_a_path_whose_corners_do_not_fit_the_turn_radius_is_refused_with_the_numbers() -> None:
    turn = SCENARIOS / "fig7_turn_vn_dynamic.toml"
    # R = 2.0 / 0.2 = 10 m: the 20 m middle segment holds its two 90 deg corners (R each), just.
    assert sm.load(turn, {"leader.speed_mps": 2.0, "leader.turn_rate_rps": 0.2}).leader.speed_mps == 2.0
    with pytest.raises(sm.ScenarioError) as err:
        sm.load(turn, {"leader.speed_mps": 2.5, "leader.turn_rate_rps": 0.2})
    assert str(err.value).endswith(
        "leader.waypoints: the leader cannot turn these corners at leader.speed_mps = 2.5 and"
        " leader.turn_rate_rps = 0.2 (turn radius R = 12.5 m): segment (0.0, 20.0) -> (20.0, 20.0) is 20 m long,"
        " its corners take 25 m (R tan(theta / 2) per corner, R = 12.5 m)"
    )


def test_leader_corners_is_pursuit_by_default_and_checked() -> None:
    turn = SCENARIOS / "fig7_turn_vn_dynamic.toml"
    assert sm.load(turn).leader.corners == "pursuit"
    assert sm.load(turn, {"leader.corners": "arcs", "leader.speed_mps": 1.6}).leader.corners == "arcs"
    with pytest.raises(sm.ScenarioError, match="leader.corners must be one of 'pursuit', 'arcs', got 'round'"):
        sm.load(turn, {"leader.corners": "round"})


def test_a_custom_formation_of_fewer_robots_than_the_run_says_what_scales() -> None:
    with pytest.raises(sm.ScenarioError) as info:
        sm.load(SCENARIOS / "fig7_turn_vn_dynamic.toml", overrides={"run.robots": 30})
    assert str(info.value).endswith(
        "formations.two covers robots 1-2, the run has robots 1-30; a custom formation places the robots its slots"
        ' name, a shape (e.g. formations.two.shape = "wedge") places any number'
    )
