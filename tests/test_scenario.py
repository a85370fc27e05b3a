"""Scenario files: the shipped ones load; bad keys and values fail with the key's name."""

from __future__ import annotations

from pathlib import Path

import pytest

from formation_swarm import scenario as sm
from tests.conftest import SCENARIOS

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
        ({"links.obs_drop": 1.5}, "links.obs_drop must be a probability in [0, 1], got 1.5"),
        ({"run.dt_s": -0.05}, "run.dt_s must be > 0, got -0.05"),
        ({"run.dt_s": "fast"}, "run.dt_s must be"),
        ({"run.robots": 1}, f"run.robots must be in [2, {sm.MAX_ROBOTS}], got 1"),
        ({"run.robots": sm.MAX_ROBOTS + 1}, f"run.robots must be in [2, {sm.MAX_ROBOTS}]"),
        ({"obstacles": [{"x_m": 0.0, "y_m": 0.0, "radius_m": 1.0}] * (sm.MAX_OBSTACLES + 1)},
         f"at most {sm.MAX_OBSTACLES} obstacles, got {sm.MAX_OBSTACLES + 1}"),
        ({"obstacles": [{"x_m": 0.0, "y_m": 0.0, "radius": 1.0}]}, "did you mean 'radius_m'?"),
    ],
)  # fmt: skip
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
