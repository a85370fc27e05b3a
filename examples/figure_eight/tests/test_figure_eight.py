"""The figure-eight leader flown through formation-swarm's ``Engine``, in
this process (no process started, each test well under 2 s): its eight,
its one formation change, its end where it began, and the same digest run
after run; then the policy alone, built from a setup by hand."""

from __future__ import annotations

import math
from pathlib import Path

from figure_eight import FigureEight

from formation_swarm import Engine, LeaderParams, LeaderSensing, LeaderSetup, Pose

SCENARIO = Path(__file__).resolve().parent.parent / "figure_eight.toml"


def test_it_flies_the_eight_changes_formation_once_and_ends_where_it_began() -> None:
    engine = Engine(SCENARIO)
    left, right = (0.0, 6.0), (0.0, -6.0)  # the circles' centres: 6 m to each side of the start, heading +x
    off_m = 0.0
    while engine.step():  # one tick (0.05 s) each
        x, y, _ = engine.poses[1]
        off_m = max(off_m, min(abs(math.dist((x, y), c) - 6.0) for c in (left, right)))
    res = engine.run()
    s = res.summary
    assert (res.exit_code, res.end_reason, s["controller_failures"]) == (0, "leader_finished", [])
    assert s["laws"]["leader"] == "figure_eight:FigureEight"
    assert off_m < 0.05  # measured 4 mm
    assert math.dist(engine.poses[1][:2], (0.0, 0.0)) < 0.5  # measured 5 cm
    assert 2 * 2 * math.pi * 6.0 / 1.5 < res.ticks * 0.05 < 52.0  # two loops of 37.7 m at 1.5 m/s: 50.35 s
    # One change, triangle -> line, where the circles meet (25.15 s), taken by both followers a tick later.
    changes = [(e["robot"], e["formation"]) for e in s["formation_events"]]
    assert changes == [(1, "line"), (2, "line"), (3, "line")]
    assert res.followers["2"]["rms_m"] < 0.6  # measured 0.42 m
    assert res.followers["3"]["rms_m"] < 2.0  # measured 1.44 m: at the end of a chain, on a circle
    assert s["collisions"] == 0


def test_two_runs_of_a_seed_give_one_digest() -> None:
    short = {"run.duration_s": 15.0, "leader.params.radius_m": 5}
    engine = Engine(SCENARIO, overrides=short, faults=["drop obs:1@2s for=3s p=0.3"])
    first = engine.run()
    engine.reset()
    again = engine.run()
    other = Engine(SCENARIO, overrides={**short, "leader.params.radius_m": 7.0}).run()
    assert first.trajectory_digest == again.trajectory_digest != other.trajectory_digest
    assert first.end_reason == "duration_reached"


def test_alone_it_turns_left_on_its_first_circle() -> None:
    params = LeaderParams(
        waypoints=((0.0, 0.0), (1.0, 0.0)),
        speed_mps=1.5,
        turn_rate_rps=0.25,
        lookahead_m=1.0,
        corners="pursuit",
        sensing_range_m=6.0,
        clear_after_s=2.0,
        code_burst_s=1.0,
        code_period_s=0.5,
    )
    setup = LeaderSetup(
        robot_id=1,
        params=params,
        formations=("triangle", "line"),
        formation=0,
        avoid_formation=1,
        dt_s=0.05,
        width_m=0.5,
        max_wheel_mps=3.0,
        seed=1,
        policy_params={**FigureEight.PARAMS, "radius_m": 5.0},
    )
    eight = FigureEight(setup)
    move = eight.step(LeaderSensing(pose=Pose(0.0, 0.0, 0.0), obstacles=()))
    # On the circle, heading along it: the turn rate v / R = 0.3 rad/s, the right wheel 0.3 * 0.25 m/s faster.
    assert (move.left_mps, move.right_mps) == (1.5 - 0.075, 1.5 + 0.075)
    assert (move.formation, move.send_code, move.finished) == (0, True, False)
    assert eight.step(None).left_mps == move.left_mps  # nothing sensed: its last wheels
