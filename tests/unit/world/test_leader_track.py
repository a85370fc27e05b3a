"""The leader's distance from its path (world.leader_track), in the world's summary."""

from __future__ import annotations

import math

import pytest

from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.studies.tables import metrics
from formation_swarm.world.engine import WorldEngine
from formation_swarm.world.leader_track import LeaderTrack, distance_to_segment

PATH = ((0.0, 0.0), (0.0, 20.0), (20.0, 20.0))


def test_the_distance_is_to_the_nearest_point_of_the_polyline() -> None:
    assert distance_to_segment(3.0, 4.0, (0.0, 0.0), (0.0, 10.0)) == 3.0  # beside the segment
    assert distance_to_segment(3.0, -4.0, (0.0, 0.0), (0.0, 10.0)) == 5.0  # before its start: to the end point
    assert distance_to_segment(1.0, 1.0, (2.0, 2.0), (2.0, 2.0)) == pytest.approx(math.sqrt(2))  # a point
    track = LeaderTrack(PATH)
    assert track.off_path_m(-1.0, 10.0) == 1.0
    assert track.off_path_m(10.0, 25.0) == 5.0  # the second leg is nearer
    assert track.off_path_m(25.0, 20.0) == 5.0  # past the last waypoint


def test_the_largest_distance_over_the_run_and_the_end_from_the_last_waypoint() -> None:
    track = LeaderTrack(PATH)
    for x, y in ((0.0, 0.0), (0.5, 10.0), (5.05, 25.05), (20.0, 21.0)):
        track.add(x, y)
    out = track.as_dict((21.0, 18.0))
    assert out["max_off_path_m"] == pytest.approx(5.05)
    assert out["end_from_last_waypoint_m"] == pytest.approx(math.hypot(1.0, 2.0))


def test_the_summary_and_a_sweeps_row_say_where_the_leader_flew() -> None:
    sc = scenario_mod.load("fig7_turn_vn_dynamic")
    eng = WorldEngine(sc, 1)
    for _ in range(100):  # straight ahead at 1.5 m/s for 5 s: on the first leg
        eng.set_command(1, 1.5, 1.5, 0, eng.time_s)
        eng.step(eng.time_s)
    path = eng.summary()["leader_path"]
    assert path["max_off_path_m"] == pytest.approx(0.0, abs=1e-9)
    assert path["end_from_last_waypoint_m"] == pytest.approx(math.hypot(20.0, 40.0 - 7.5))
    row = metrics({"parts": {"world": eng.summary()}})
    assert (row["leader_off_path_m"], row["leader_end_m"]) == (path["max_off_path_m"], path["end_from_last_waypoint_m"])
