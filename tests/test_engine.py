"""The world engine's metrics: what the summary, the sweeps and docs/results.md
report. Driven tick by tick with chosen commands, no processes."""

from __future__ import annotations

import math

import pytest

from formation_swarm import scenario as scenario_mod
from formation_swarm.world.engine import TURN_RATE_RPS, WorldEngine
from formation_swarm.world.kinematics import Pose, from_body_frame
from tests.conftest import SCENARIOS

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")  # three robots: 1 leads 2, 2 leads 3
TURN = scenario_mod.load(SCENARIOS / "fig7_turn_vn_dynamic.toml")  # two robots, R2 offset (-1.5, -1.5)


def _drive(eng: WorldEngine, ticks: int, commands: dict[int, tuple[float, float]]) -> None:
    for _ in range(ticks):
        for rid, (left, right) in commands.items():
            eng.set_command(rid, left, right, eng.robots[rid].formation, eng.time_s)
        eng.step(eng.time_s)


@pytest.mark.parametrize("robot", [1, 2, 3])
def test_the_digest_covers_every_robot(robot: int) -> None:
    """Same run, same digest; one robot's trajectory changed for one tick (any
    robot, the last one too), another digest."""
    straight = {rid: (1.0, 1.0) for rid in FIG11.robots}
    a, b, c = WorldEngine(FIG11, 0), WorldEngine(FIG11, 0), WorldEngine(FIG11, 0)
    for eng in (a, b, c):
        _drive(eng, 10, straight)
    _drive(c, 1, {**straight, robot: (1.0, 1.001)})
    for eng in (a, b):
        _drive(eng, 1, straight)
    for eng in (a, b, c):
        _drive(eng, 10, straight)
    assert a.digest() == b.digest()
    assert c.digest() != a.digest()


def test_the_digest_covers_every_tick() -> None:
    a, b = WorldEngine(TURN, 0), WorldEngine(TURN, 0)
    straight = {1: (1.0, 1.0), 2: (1.0, 1.0)}
    _drive(a, 5, straight)
    _drive(b, 5, straight)
    b.robots[2].pose = Pose(*b.robots[2].pose[:2], b.robots[2].pose[2] + 1e-9)  # tick 5 only, by a hair
    _drive(a, 1, straight)
    _drive(b, 1, straight)
    assert a.digest() != b.digest()


def _follower_behind_its_target(lag_m: float, right_m: float = 0.0) -> WorldEngine:
    """R2 placed ``lag_m`` behind its true target (and ``right_m`` to its right)."""
    eng = WorldEngine(TURN, 0)
    slot = TURN.formations["two"].slots[2]
    ref = eng.robots[1].pose
    tx, ty = from_body_frame(ref, slot.offset.x_m + right_m, slot.offset.y_m - lag_m)
    eng.robots[2].pose = Pose(tx, ty, ref.theta_rad)
    return eng


def test_formation_error_rms_max_and_lag_on_a_known_offset() -> None:
    eng = _follower_behind_its_target(0.6, right_m=0.8)  # 1.0 m from its target
    _drive(eng, 20, {1: (1.0, 1.0), 2: (1.0, 1.0)})  # both straight at the same speed: the error stays
    m = eng.summary()["followers"]["2"]
    assert m["samples"] == 20
    assert m["rms_m"] == pytest.approx(1.0, abs=1e-9)
    assert m["max_m"] == pytest.approx(1.0, abs=1e-9)
    assert m["max_lag_m"] == pytest.approx(0.6, abs=1e-9)  # behind its target along the leader's heading
    assert m["max_ahead_m"] == 0.0
    assert m["straight_rms_m"] == pytest.approx(1.0, abs=1e-9)
    assert m["turn_samples"] == 0
    assert math.isnan(m["turn_rms_m"])
    assert math.isnan(m["turn_mean_lag_m"])
    ahead = _follower_behind_its_target(-0.5)
    _drive(ahead, 4, {1: (1.0, 1.0), 2: (1.0, 1.0)})
    m = ahead.summary()["followers"]["2"]
    assert m["max_ahead_m"] == pytest.approx(0.5, abs=1e-9)
    assert m["max_lag_m"] == 0.0


def test_in_the_turn_is_the_reference_turning_not_the_follower() -> None:
    """Claim b's split: a sample is "in the turn" when the follower's reference
    turns at >= TURN_RATE_RPS (from its wheel commands), whatever the follower does."""
    w = TURN.width_m * TURN_RATE_RPS  # wheel-speed difference at exactly the threshold
    ref_turns = WorldEngine(TURN, 0)
    _drive(ref_turns, 10, {1: (1.0, 1.0 + w), 2: (1.0, 1.0)})
    own_turns = WorldEngine(TURN, 0)
    _drive(own_turns, 10, {1: (1.0, 1.0), 2: (1.0 + 2 * w, 1.0)})
    slow_turn = WorldEngine(TURN, 0)
    _drive(slow_turn, 10, {1: (1.0, 1.0 + 0.9 * w), 2: (1.0, 1.0)})
    assert ref_turns.summary()["followers"]["2"]["turn_samples"] == 10
    assert own_turns.summary()["followers"]["2"]["turn_samples"] == 0
    assert slow_turn.summary()["followers"]["2"]["turn_samples"] == 0
    m = ref_turns.summary()["followers"]["2"]
    assert m["turn_rms_m"] == pytest.approx(m["rms_m"])
    assert math.isnan(m["straight_rms_m"])


def test_turn_and_straight_rms_split_the_samples() -> None:
    eng = _follower_behind_its_target(0.0)  # on its target: error 0 while straight
    _drive(eng, 10, {1: (1.0, 1.0), 2: (1.0, 1.0)})
    _drive(eng, 10, {1: (1.0, 1.2), 2: (0.0, 0.0)})  # the leader turns, the follower waits: errors grow
    m = eng.summary()["followers"]["2"]
    assert m["samples"] == 20
    assert m["turn_samples"] == 10
    assert m["straight_rms_m"] == pytest.approx(0.0, abs=1e-9)
    assert m["turn_rms_m"] > 0.1
    assert m["rms_m"] == pytest.approx(m["turn_rms_m"] / math.sqrt(2), rel=1e-9)
    assert m["turn_mean_lag_m"] > 0.0


def test_contacts_count_once_per_touch_and_the_closest_distance() -> None:
    eng = WorldEngine(FIG11, 0)
    d = FIG11.diameter_m
    leader = eng.robots[1].pose
    eng.robots[2].pose = Pose(leader.x_m + 0.9 * d, leader.y_m, leader.theta_rad)  # touching R1
    _drive(eng, 3, {})  # standing still: one contact, not three
    s = eng.summary()
    assert s["collisions"] == 1
    assert s["min_distance_m"] == pytest.approx(0.9 * d)
    eng.robots[2].pose = Pose(leader.x_m + 5.0, leader.y_m, leader.theta_rad)  # apart ...
    _drive(eng, 1, {})
    eng.robots[2].pose = Pose(leader.x_m + 0.5 * d, leader.y_m, leader.theta_rad)  # ... and touching again
    _drive(eng, 1, {})
    s = eng.summary()
    assert s["collisions"] == 2
    assert s["min_distance_m"] == pytest.approx(0.5 * d)
    assert s["obstacle_collisions"] == 0


def test_an_obstacle_contact_is_counted_apart() -> None:
    eng = WorldEngine(FIG11, 0)
    ob = FIG11.obstacles[0]
    eng.robots[3].pose = Pose(ob.x_m + ob.radius_m + 0.4 * FIG11.diameter_m, ob.y_m, 0.0)
    _drive(eng, 2, {})
    s = eng.summary()
    assert s["obstacle_collisions"] == 1
    assert s["collisions"] == 0


def test_a_stale_command_stops_the_robot_and_is_counted() -> None:
    eng = WorldEngine(TURN, 0)
    eng.set_command(1, 1.0, 1.0, 0, 0.0)
    start = eng.robots[1].pose
    ticks = round(TURN.stale_after_s / TURN.dt_s)
    for _ in range(ticks):
        eng.step(eng.time_s)  # within stale_after_s: still driving
    moving = eng.robots[1].pose
    assert moving.y_m - start.y_m == pytest.approx(ticks * TURN.dt_s * 1.0)
    eng.step(eng.time_s + 1e-6)  # now older than stale_after_s
    assert eng.robots[1].pose == moving
    assert eng.stale_stops == 1
    eng.step(eng.time_s)
    assert eng.stale_stops == 1  # counted once


def test_a_formation_event_per_robot_and_change() -> None:
    eng = WorldEngine(FIG11, 0)
    line = FIG11.code_of("line")
    eng.step(0.0)
    eng.set_command(2, 0.0, 0.0, line, eng.time_s)
    eng.set_command(2, 0.0, 0.0, line, eng.time_s)  # the same code again: no new event
    eng.set_command(3, 0.0, 0.0, len(FIG11.formation_names), eng.time_s)  # no such formation: ignored
    assert eng.formation_events == [{"tick": 1, "time_s": FIG11.dt_s, "robot": 2, "formation": "line"}]
    assert eng.robots[3].formation == FIG11.code_of("triangle")
