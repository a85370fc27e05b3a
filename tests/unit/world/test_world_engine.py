"""The world engine driven directly: what it executes of a command."""

from __future__ import annotations

import math

import pytest

from formation_swarm.spec import scenario as sm
from formation_swarm.world.engine import WorldEngine


def test_a_command_beyond_the_motors_is_clamped_and_counted() -> None:
    sc = sm.load("fig11_obstacles")
    eng = WorldEngine(sc, seed=1)
    x0, y0, th0 = eng.robots[3].pose
    eng.set_command(3, 1e308, 1e308, 0, now_s=0.0)  # schema-valid, physically absurd
    eng.step(0.0)
    x1, y1, _ = eng.robots[3].pose
    assert math.hypot(x1 - x0, y1 - y0) == pytest.approx(sc.max_wheel_mps * sc.dt_s, rel=1e-9)
    eng.set_command(3, -1e308, 2.0, 0, now_s=sc.dt_s)
    eng.step(sc.dt_s)
    eng.set_command(3, 1.0, 1.0, 0, now_s=2 * sc.dt_s)  # within the limit: executed as sent
    assert eng.robots[3].command == (1.0, 1.0)
    assert eng.summary()["clamped_commands"] == 2


def test_a_command_at_the_limit_is_not_clamped_and_one_below_it_is_clamped_to_it() -> None:
    sc = sm.load("fig11_obstacles")
    eng = WorldEngine(sc, seed=1)
    lim = sc.max_wheel_mps
    for cmd in ((lim, -lim), (-lim, lim), (0.0, -lim), (-lim, 0.0)):
        eng.set_command(3, *cmd, 0, now_s=0.0)
        assert eng.robots[3].command == cmd
    assert eng.clamped_commands == 0
    eng.set_command(3, -1e9, 0.0, 0, now_s=0.0)
    assert eng.robots[3].command == (-lim, 0.0)
    eng.set_command(3, 0.0, -1e9, 0, now_s=0.0)
    assert eng.robots[3].command == (0.0, -lim)
    assert eng.clamped_commands == 2


def test_a_scenario_whose_controller_outruns_the_motors_is_refused() -> None:
    with pytest.raises(sm.ScenarioError, match=r"follower 2's fuzzy controller commands up to 2.5 m/s"):
        sm.load("fig11_obstacles", {"robot.max_wheel_mps": 2.4})
    with pytest.raises(sm.ScenarioError, match=r"the leader's wheels reach 3.0625 m/s"):
        sm.load("fig11_obstacles", {"leader.speed_mps": 3.0})
