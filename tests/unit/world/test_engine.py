"""The world engine's metrics: what the summary, the sweeps and docs/results.md
report. Driven tick by tick with chosen commands, no processes."""

from __future__ import annotations

import math

import pytest

from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.engine import CONTACTS_LISTED, TURN_RATE_RPS, WorldEngine
from formation_swarm.world.kinematics import Pose, from_body_frame
from formation_swarm.world.recovery import Recovery
from tests.helpers import SCENARIOS

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
    eng.robots[1].pose = leader = Pose(7.0, 3.0, 0.5)  # away from the axes
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
    # Each contact listed once, at the tick it began (ticks 0-2 touching, 3 apart, 4 touching).
    assert s["contacts"] == [{"tick": 0, "time_s": 0.0, "robots": [1, 2]}, {"tick": 4, "time_s": 0.2, "robots": [1, 2]}]


def test_only_the_first_contacts_are_listed_but_all_are_counted() -> None:
    eng = WorldEngine(FIG11, 0)
    d = FIG11.diameter_m
    eng.robots[1].pose = leader = Pose(7.0, 3.0, 0.5)
    for k in range(CONTACTS_LISTED + 10):  # touch, part, touch, ...
        gap = 0.5 * d if k % 2 == 0 else 5.0
        eng.robots[2].pose = Pose(leader.x_m + gap, leader.y_m, leader.theta_rad)
        _drive(eng, 1, {})
    s = eng.summary()
    assert s["collisions"] == (CONTACTS_LISTED + 10) // 2
    assert len(s["contacts"]) == min(CONTACTS_LISTED, s["collisions"])
    assert [c["tick"] for c in s["contacts"]] == list(range(0, 2 * len(s["contacts"]), 2))


def test_an_obstacle_contact_is_counted_apart() -> None:
    eng = WorldEngine(FIG11, 0)
    ob = FIG11.obstacles[0]
    eng.robots[3].pose = Pose(ob.x_m + ob.radius_m + 0.6 * FIG11.diameter_m, ob.y_m, 0.0)  # clear of it
    _drive(eng, 2, {})
    assert eng.summary()["obstacle_collisions"] == 0
    eng.robots[3].pose = Pose(ob.x_m + ob.radius_m + 0.4 * FIG11.diameter_m, ob.y_m, 0.0)  # touching
    _drive(eng, 2, {})
    s = eng.summary()
    assert s["obstacle_collisions"] == 1
    assert s["collisions"] == 0
    assert s["contacts"] == [{"tick": 2, "time_s": 0.1, "robot": 3, "obstacle": 0}]


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
    assert eng.formation_events == [{"tick": 1, "time_s": FIG11.dt_s, "robot": 2, "formation": "line"}]


def test_the_summary_lists_one_ticks_formation_events_by_robot_whatever_their_commands_order() -> None:
    eng = WorldEngine(FIG11, 0)
    line = FIG11.code_of("line")
    eng.step(0.0)
    eng.set_command(3, 0.0, 0.0, line, eng.time_s)  # robot 3's command came first this tick
    eng.set_command(2, 0.0, 0.0, line, eng.time_s)
    eng.step(eng.time_s)
    eng.set_command(1, 0.0, 0.0, line, eng.time_s)
    assert [(e["tick"], e["robot"]) for e in eng.summary()["formation_events"]] == [(1, 2), (1, 3), (2, 1)]


OFF_AXES = """
[run]
robots = 3
duration_s = 10.0
[leader]
waypoints = [[10.0, 20.0], [13.0, 24.0]]
formation = "wedge"
sensing_range_m = 5.0
[formations.wedge]
shape = "wedge"
lateral_m = 1.5
back_m = 1.5
[[obstacles]]
x_m = 30.0
y_m = 20.0
radius_m = 1.0
[[obstacles]]
x_m = 30.8
y_m = 20.0
radius_m = 0.5
"""


@pytest.fixture
def off_axes(tmp_path: object) -> WorldEngine:
    path = tmp_path / "off_axes.toml"  # type: ignore[operator]
    path.write_text(OFF_AXES)
    return WorldEngine(scenario_mod.load(path), 0)


def test_robots_start_on_their_slots_heading_along_the_first_leg(off_axes: WorldEngine) -> None:
    heading = math.atan2(4.0, 3.0)
    lead = off_axes.robots[1].pose
    assert lead == pytest.approx((10.0, 20.0, heading), abs=1e-12)
    for rid in (2, 3):
        pose = off_axes.robots[rid].pose
        assert pose.theta_rad == pytest.approx(heading, abs=1e-12)
        assert off_axes.true_target(rid) == pytest.approx(pose[:2], abs=1e-12)  # on its target
    assert from_body_frame(lead, -1.5, -1.5) == pytest.approx(off_axes.robots[2].pose[:2], abs=1e-12)
    # On their targets, R3's slot (3, 0) from R2 included: no error; then R3 0.6 m behind its target.
    _drive(off_axes, 1, {})
    r3 = off_axes.robots[3].pose
    off_axes.robots[3].pose = Pose(*from_body_frame(r3, 0.0, -0.6), r3.theta_rad)
    _drive(off_axes, 1, {})
    s = off_axes.summary()["followers"]
    assert s["2"]["max_m"] == pytest.approx(0.0, abs=1e-12)
    assert s["3"]["max_m"] == pytest.approx(0.6, abs=1e-12)
    assert s["3"]["max_lag_m"] == pytest.approx(0.6, abs=1e-12)


def test_the_leader_senses_obstacles_within_its_range_of_their_edge(off_axes: WorldEngine) -> None:
    sc = off_axes.scenario
    lead = off_axes.robots[1]
    for edge_gap, seen in ((sc.leader.sensing_range_m - 0.01, True), (sc.leader.sensing_range_m + 0.01, False)):
        lead.pose = Pose(30.0 - 1.0 - edge_gap, 20.0, 0.0)  # facing the first obstacle
        _, readings, obstacles = off_axes.observation(1)
        assert readings == []  # the leader has no camera
        assert bool(obstacles) is seen
    lead.pose = Pose(26.0, 20.0, 0.0)
    _, _, obstacles = off_axes.observation(1)
    assert obstacles == [pytest.approx((4.0, 0.0, 1.0)), pytest.approx((4.8, 0.0, 0.5))]  # dead ahead
    _, readings, obstacles = off_axes.observation(2)
    assert obstacles == []  # followers sense no obstacle
    assert [r[0] for r in readings] == [3]  # the leader, moved 16 m away, is out of camera range


def test_two_obstacles_touched_at_once_are_two_contacts(off_axes: WorldEngine) -> None:
    off_axes.robots[3].pose = Pose(30.4, 20.0, 0.0)  # inside both
    off_axes.robots[2].pose = Pose(35.0, 25.0, 0.0)
    off_axes.robots[1].pose = Pose(-5.0, 0.0, 0.0)
    _drive(off_axes, 2, {})
    s = off_axes.summary()
    assert (s["obstacle_collisions"], s["collisions"]) == (2, 0)
    assert s["min_distance_m"] == pytest.approx(math.hypot(4.6, 5.0))
    assert [(c["robot"], c["obstacle"]) for c in s["contacts"]] == [(3, 0), (3, 1)]


def test_a_killed_robot_stops_for_good() -> None:
    eng = WorldEngine(TURN, 0)
    eng.kill(2)
    pose = eng.robots[2].pose
    _drive(eng, 5, {1: (1.0, 1.0), 2: (1.0, 1.0)})
    assert eng.robots[2].pose == pose
    assert eng.alive_ids == [1]
    s = eng.summary()
    assert s["dead_robots"] == [2]
    assert s["final_poses"]["1"][1] > pose.y_m  # the other one flew on


def test_a_killed_reference_stands_with_its_command_zeroed() -> None:
    """A dead reference commands nothing: its follower's samples are not "in a turn"."""
    eng = WorldEngine(TURN, 0)
    eng.set_command(1, 1.0, 1.5, 0, 0.0)  # turning when it dies
    eng.kill(1)
    assert eng.robots[1].command == (0.0, 0.0)
    _drive(eng, 5, {2: (1.0, 1.0)})
    f = eng.summary()["followers"]["2"]
    assert (f["samples"], f["turn_samples"]) == (5, 0)


def test_a_killed_followers_error_until_its_first_stop_is_kept_apart() -> None:
    eng = WorldEngine(TURN, 0)
    _drive(eng, 20, {1: (1.0, 1.0), 2: (1.0, 1.0)})
    before = eng.summary()["followers"]["2"]
    assert "until_stopped" not in before
    eng.kill(2)
    _drive(eng, 40, {1: (1.0, 1.0)})  # its target drives off: the error grows
    eng.revive(2)
    eng.kill(2)  # a second stop keeps the first's figures
    after = eng.summary()["followers"]["2"]
    assert after["until_stopped"] == {"time_s": 20 * TURN.dt_s, "rms_m": before["rms_m"], "max_m": before["max_m"]}
    assert after["rms_m"] > before["rms_m"] + 0.5
    assert after["samples"] == before["samples"] + 40


def test_a_revived_reference_stands_until_its_first_command() -> None:
    eng = WorldEngine(TURN, 0)
    eng.set_command(1, 1.0, 1.5, 0, 0.0)
    eng.kill(1)
    eng.revive(1)
    assert eng.robots[1].command == (0.0, 0.0)
    pose = eng.robots[1].pose
    _drive(eng, 3, {2: (1.0, 1.0)})
    assert eng.robots[1].pose == pose
    assert eng.summary()["followers"]["2"]["turn_samples"] == 0


def test_a_recovery_gets_each_tick_under_its_own_number() -> None:
    eng = WorldEngine(TURN, 0)
    tx, ty = eng.true_target(2)
    pose = eng.robots[2].pose
    rec = Recovery(robot=2, event="thawed", fault=None, since_tick=0, watched=(2,), dt_s=TURN.dt_s)
    eng.recoveries.append(rec)
    _drive(eng, 3, {1: (1.0, 1.0), 2: (1.0, 1.0)})
    eng.record()
    assert rec.error_at_start_m == pytest.approx(math.hypot(tx - pose.x_m, ty - pose.y_m))  # tick 0's error


def test_a_stale_reversing_command_is_counted_too() -> None:
    eng = WorldEngine(TURN, 0)
    eng.set_command(1, -0.5, 0.2, 0, 0.0)
    eng.step(1.0)
    assert eng.stale_stops == 1


def test_follower_metrics_from_samples() -> None:
    from formation_swarm.world.engine import METRICS, FollowerMetrics

    m = FollowerMetrics()
    m.add(3.0, 2.0, turning=True)
    m.add(4.0, -0.5, turning=True)
    m.add(1.0)  # along the heading: 0 unless given
    d = m.as_dict()
    # No camera frame was taken: whether it saw its reference is not known, and the metrics stand.
    assert (d.pop("acquired"), d.pop("frames"), d.pop("seen_ticks")) == (None, 0, 0)
    assert d == pytest.approx(
        {
            "rms_m": math.sqrt(26 / 3),
            "max_m": 4.0,
            "samples": 3,
            "turn_rms_m": math.sqrt(12.5),
            "straight_rms_m": 1.0,
            "turn_max_m": 4.0,
            "turn_samples": 2,
            "turn_mean_lag_m": 0.75,
            "max_lag_m": 2.0,
            "max_ahead_m": 0.5,
        }
    )
    solo = FollowerMetrics()
    solo.add(1.0)  # no along-heading error given: neither behind nor ahead
    assert (solo.max_lag_m, solo.max_ahead_m) == (0.0, 0.0)
    # No sample (a run that ended before its first tick): every metric unknown, none a 0 m that reads as perfect.
    empty = FollowerMetrics().as_dict()
    assert empty["samples"] == 0
    assert all(empty[k] is None for k in METRICS), empty
    # Samples but no turn: the turn's largest error is unknown too, not 0 m.
    straight = FollowerMetrics()
    straight.add(0.5)
    assert straight.as_dict()["turn_max_m"] is None
    assert math.isnan(straight.as_dict()["turn_rms_m"])  # written as null


def test_error_windows_give_each_followers_mean_and_largest_error_per_second() -> None:
    """The leader drives off at 1.5 m/s, its followers stay: robot 2's error is
    the leader's distance from its start, 0.075 m more each tick; robot 3
    keeps its place behind robot 2, error 0. 45 ticks: windows of 20, 20, 5."""
    eng = WorldEngine(FIG11, 0)
    _drive(eng, 45, {1: (1.5, 1.5), 2: (0.0, 0.0), 3: (0.0, 0.0)})
    w = eng.summary()["error_windows"]
    assert w["window_s"] == pytest.approx(1.0)
    step = 1.5 * FIG11.dt_s
    assert w["mean_m"]["2"] == pytest.approx([step * 9.5, step * 29.5, step * 42.0], abs=1e-4)
    assert w["max_m"]["2"] == pytest.approx([step * 19, step * 39, step * 44], abs=1e-4)
    assert w["mean_m"]["3"] == w["max_m"]["3"] == [0.0, 0.0, 0.0]


def test_a_follower_that_never_sees_its_reference_has_no_metrics() -> None:
    """Cameras that see no farther than 1.8 m (a range fault for the whole run):
    R2 starts 2.05 m from R1, R3 3 m from R2. Neither ever sees its reference;
    R3's (R2) never moves, so its error would be 0."""
    short = ["range 2@0s m=1.8", "range 3@0s m=1.8"]
    sc = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml", faults=short)
    eng = WorldEngine(sc, 0)
    for _ in range(40):
        for rid in sc.robots:
            eng.observation(rid)
        eng.set_command(1, 1.5, 1.5, eng.robots[1].formation, eng.time_s)  # the leader drives off
        eng.step(eng.time_s)
    m = eng.summary()["followers"]
    for rid in ("2", "3"):
        assert m[rid]["acquired"] is False
        assert (m[rid]["frames"], m[rid]["seen_ticks"], m[rid]["samples"]) == (40, 0, 40)
        assert all(m[rid][k] is None for k in ("rms_m", "max_m", "turn_rms_m", "straight_rms_m", "max_ahead_m"))
    # R3's camera alone at 2.5 m: R2 sees R1 from the first frame; R3 (3 m from R2) still never sees R2.
    eng = WorldEngine(scenario_mod.load(SCENARIOS / "fig11_obstacles.toml", faults=["range 3@0s m=2.5"]), 0)
    for _ in range(5):
        for rid in sc.robots:
            eng.observation(rid)
        eng.step(eng.time_s)
    m = eng.summary()["followers"]
    assert (m["2"]["acquired"], m["2"]["seen_ticks"], m["2"]["rms_m"]) == (True, 5, 0.0)
    assert (m["3"]["acquired"], m["3"]["rms_m"]) == (False, None)
