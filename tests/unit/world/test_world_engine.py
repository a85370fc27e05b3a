"""The world engine driven directly: what it executes of a command."""

from __future__ import annotations

import math

import pytest

from formation_swarm.spec import scenario as sm
from formation_swarm.world.engine import WorldEngine


def test_the_engine_runs_a_command_as_given_at_the_motors_limit() -> None:
    """The engine checks nothing: world.commands judged the command (rejected
    beyond the limit, clamped within rounding of it: tests/unit/world/test_world_inputs.py)."""
    sc = sm.load("fig11_obstacles")
    eng = WorldEngine(sc, seed=1)
    lim = sc.max_wheel_mps
    x0, y0, _ = eng.robots[3].pose
    eng.set_command(3, lim, lim, 0, now_s=0.0)
    eng.step(0.0)
    x1, y1, _ = eng.robots[3].pose
    assert math.hypot(x1 - x0, y1 - y0) == pytest.approx(lim * sc.dt_s, rel=1e-9)
    for cmd in ((lim, -lim), (-lim, lim), (0.0, -lim), (-lim, 0.0)):
        eng.set_command(3, *cmd, 0, now_s=sc.dt_s)
        assert eng.robots[3].command == cmd
    assert "clamped_commands" not in eng.summary()  # the world's tick counts them (world.tick.WorldTick.summary)


def test_a_scenario_whose_controller_outruns_the_motors_is_refused() -> None:
    with pytest.raises(sm.ScenarioError, match=r"follower 2's fuzzy controller commands up to 2.5 m/s"):
        sm.load("fig11_obstacles", {"robot.max_wheel_mps": 2.4})
    with pytest.raises(sm.ScenarioError, match=r"the leader's wheels reach 3.0625 m/s"):
        sm.load("fig11_obstacles", {"leader.speed_mps": 3.0})
