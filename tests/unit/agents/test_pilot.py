"""The leader's pilot: pure pursuit along the waypoints at the cruise speed."""

from __future__ import annotations

import math

import pytest

from formation_swarm.agents.pilot import NoRoom, PathPilot, no_room, round_corners, turn_room
from formation_swarm.studies.sim import PAPER_TURNING_PATH
from formation_swarm.world.kinematics import Pose, step

NORTH = math.pi / 2


def test_on_a_straight_path_both_wheels_run_at_the_cruise_speed() -> None:
    pilot = PathPilot(((0.0, 0.0), (0.0, 50.0)), speed_mps=1.5, width_m=0.5)
    assert pilot.step(Pose(0.0, 10.0, NORTH)) == (1.5, 1.5)


def test_a_path_to_the_right_turns_right_at_the_curvature_or_the_largest_rate() -> None:
    # Off the path by 0.5 m to its left: the goal 1 m ahead on the path is at (0.5, ~1) in the body frame.
    pilot = PathPilot(((0.0, 0.0), (0.0, 50.0)), speed_mps=1.0, width_m=0.5, lookahead_m=1.0, max_turn_rate_rps=2.0)
    left, right = pilot.step(Pose(-0.5, 10.0, NORTH))
    # Goal (0, 11): body frame x = 0.5 right, y = 1 ahead; curvature -2 x / d^2 = -0.8 1/m.
    omega = 1.0 * -2.0 * 0.5 / (0.5**2 + 1.0**2)
    assert left == pytest.approx(1.0 - 0.5 * omega * 0.5)
    assert right == pytest.approx(1.0 + 0.5 * omega * 0.5)
    assert left > right  # a faster left wheel turns right
    slow = PathPilot(((0.0, 0.0), (0.0, 50.0)), speed_mps=1.0, width_m=0.5, max_turn_rate_rps=0.25)
    left, right = slow.step(Pose(-0.5, 10.0, NORTH))
    assert (right - left) / 0.5 == pytest.approx(-0.25)  # clipped to the largest turn rate


def test_it_stops_at_the_end_and_stays_stopped() -> None:
    pilot = PathPilot(((0.0, 0.0), (0.0, 10.0)), speed_mps=1.5, width_m=0.5, lookahead_m=1.0)
    assert pilot.step(Pose(0.0, 9.4, NORTH)) == (1.5, 1.5)  # 0.6 m from the end: still going
    assert not pilot.finished
    assert pilot.step(Pose(0.0, 9.6, NORTH)) == (0.0, 0.0)  # within half the look-ahead
    assert pilot.finished
    assert pilot.step(Pose(0.0, 0.0, NORTH)) == (0.0, 0.0)


def test_it_flies_the_paper_path_within_a_few_centimetres_on_the_straights() -> None:
    pilot = PathPilot(PAPER_TURNING_PATH, speed_mps=1.5, width_m=0.5, max_turn_rate_rps=0.25)
    pose = Pose(0.0, 0.0, NORTH)
    track = []
    for _ in range(2000):
        left, right = pilot.step(pose)
        if pilot.finished:
            break
        pose = step(pose, left, right, 0.5, 0.05)
        track.append(pose)
    assert pilot.finished
    assert math.hypot(pose.x_m - 20.0, pose.y_m - 40.0) < 0.5  # at the last waypoint
    # Path length 60 m at 1.5 m/s: 40 s; 44.95 s measured, the wide turns at 0.25 rad/s.
    assert 44.0 < len(track) * 0.05 < 46.0
    first_leg = [p for p in track if p.y_m < 15.0]
    assert max(abs(p.x_m) for p in first_leg) < 0.05
    assert max(abs(p.theta_rad - NORTH) for p in first_leg) < 1e-9  # straight north until the first turn
    # It passes by each corner (measured: 0.08 m and 0.53 m from them).
    for cx, cy in PAPER_TURNING_PATH[1:3]:
        assert min(math.hypot(p.x_m - cx, p.y_m - cy) for p in track) < 0.6


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"waypoints": ((0.0, 0.0),)}, "waypoints"),
        ({"waypoints": ((0.0, 0.0), (1.0, math.nan))}, r"waypoints\[1\]"),
        ({"speed_mps": 0.0}, "speed_mps"),
        ({"lookahead_m": -1.0}, "lookahead_m"),
        ({"max_turn_rate_rps": 0.0}, "max_turn_rate_rps"),
    ],
)
def test_bad_parameters_name_themselves(kwargs: dict, name: str) -> None:
    args = {"waypoints": ((0.0, 0.0), (0.0, 1.0)), "speed_mps": 1.0, "width_m": 0.5, **kwargs}
    with pytest.raises(ValueError, match=name):
        PathPilot(**args)


def test_the_goal_is_the_look_ahead_point_on_a_segment_away_from_the_origin() -> None:
    # A 1 m leg from (5, 3) going north, look-ahead 0.5 m; the robot 0.2 m east of it, 0.3 m along.
    pilot = PathPilot(
        ((5.0, 3.0), (5.0, 4.0), (5.0, 9.0)), speed_mps=1.0, width_m=0.5, lookahead_m=0.5, max_turn_rate_rps=10.0
    )
    left, right = pilot.step(Pose(5.2, 3.3, NORTH))
    # Goal (5, 3.8): body frame x = -0.2 (left), y = 0.5; curvature 2 * 0.2 / 0.29.
    omega = 2.0 * 0.2 / (0.2**2 + 0.5**2)
    assert (left, right) == pytest.approx((1.0 - 0.25 * omega, 1.0 + 0.25 * omega), abs=1e-12)


def test_the_projection_on_a_leg_along_x_away_from_the_origin() -> None:
    # A 1 m leg from (5, 3) going east, look-ahead 0.5 m; the robot 0.3 m along it, 0.2 m north of it.
    pilot = PathPilot(
        ((5.0, 3.0), (6.0, 3.0), (9.0, 3.0)), speed_mps=1.0, width_m=0.5, lookahead_m=0.5, max_turn_rate_rps=10.0
    )
    left, right = pilot.step(Pose(5.3, 3.2, 0.0))
    # Goal (5.8, 3): body frame x = 0.2 (right), y = 0.5.
    omega = -2.0 * 0.2 / (0.2**2 + 0.5**2)
    assert (left, right) == pytest.approx((1.0 - 0.25 * omega, 1.0 + 0.25 * omega), abs=1e-12)


def test_a_repeated_waypoint_is_flown_through() -> None:
    pilot = PathPilot(((0.0, 0.0), (0.0, 5.0), (0.0, 5.0)), speed_mps=1.0, width_m=0.5)
    pose = Pose(0.0, 0.0, NORTH)
    for _ in range(200):
        left, right = pilot.step(pose)
        if pilot.finished:
            break
        pose = step(pose, left, right, 0.5, 0.05)
    assert pilot.finished
    assert pose.y_m == pytest.approx(4.5, abs=0.1)  # stops half a look-ahead before the end


def test_it_stops_only_near_the_end_of_the_last_leg() -> None:
    # The path comes back next to an earlier corner: passing that corner is not the end.
    pilot = PathPilot(((0.0, 0.0), (0.0, 10.0), (4.0, 10.0), (0.3, 10.2)), speed_mps=1.0, width_m=0.5)
    pilot.step(Pose(0.0, 9.5, NORTH))  # the corner is within the look-ahead: on to the second leg
    assert pilot.step(Pose(0.0, 9.9, NORTH)) != (0.0, 0.0)
    assert not pilot.finished


def test_the_stop_distance_is_half_the_look_ahead() -> None:
    path = ((0.0, 0.0), (0.0, 10.0))
    assert PathPilot(path, 1.0, 0.5, lookahead_m=2.0).step(Pose(0.0, 8.9, NORTH)) != (0.0, 0.0)
    assert PathPilot(path, 1.0, 0.5, lookahead_m=2.0).step(Pose(0.0, 9.1, NORTH)) == (0.0, 0.0)
    assert PathPilot(path, 1.0, 0.5, lookahead_m=2.0).step(Pose(0.0, 9.0, NORTH)) == (1.0, 1.0)  # 1.0 m: not within


def test_a_pilot_started_along_the_path_goes_on_from_there_not_back_to_the_start() -> None:
    """A leader restarted mid-run: its fresh pilot picks the segment nearest its pose."""
    path = ((0.0, 0.0), (0.0, 20.0), (20.0, 20.0), (20.0, 0.0))
    pilot = PathPilot(path, speed_mps=1.0, width_m=0.5, lookahead_m=1.0)
    assert pilot.nearest_segment(10.0, 19.0) == 1
    assert pilot.nearest_segment(0.0, 0.0) == 0
    assert pilot.nearest_segment(20.0, 20.0) == 1  # the first of equally near segments
    east = 0.0
    assert pilot.step(Pose(10.0, 20.0, east)) == (1.0, 1.0)  # on the second leg, heading along it: straight on
    # At the path's start, a fresh pilot flies the first segment, as it always did.
    fresh = PathPilot(path, speed_mps=1.0, width_m=0.5, lookahead_m=1.0)
    assert fresh.step(Pose(0.0, 0.0, NORTH)) == (1.0, 1.0)
    # A closed loop: its start is also its last segment's end; the first segment wins.
    loop = PathPilot(((0.0, 0.0), (0.0, 10.0), (10.0, 10.0), (0.0, 0.0)), speed_mps=1.0, width_m=0.5)
    assert loop.nearest_segment(0.0, 0.0) == 0


def test_the_nearest_segment_of_a_diagonal_path_and_beside_a_corner() -> None:
    zigzag = PathPilot(((0.0, 0.0), (4.0, 4.0), (8.0, 0.0)), speed_mps=1.0, width_m=0.5)
    assert zigzag.nearest_segment(3.0, 3.2) == 0  # 0.14 m from the first leg, 1.28 m from the second's start
    assert zigzag.nearest_segment(5.0, 3.2) == 1
    # Past the end of the first leg, beside where the second leg would be if it went on backwards:
    # nearest the first leg's end (2.0 m), not 0.1 m from a leg that does not reach there.
    corner = PathPilot(((0.0, 0.0), (4.0, 0.0), (4.0, -4.0)), speed_mps=1.0, width_m=0.5)
    assert corner.nearest_segment(4.1, 2.0) == 0
    # A hairpin: 0.1 m below its first leg, 1.9 m above its way back.
    hairpin = PathPilot(((0.0, 0.0), (10.0, 0.0), (10.0, -2.0), (0.0, -2.0)), speed_mps=1.0, width_m=0.5)
    assert hairpin.nearest_segment(5.0, -0.1) == 0
    assert hairpin.nearest_segment(5.0, -1.9) == 2


def test_a_goal_within_a_micrometre_is_flown_straight_at() -> None:
    """With a look-ahead under a micrometre the goal is about where the robot is:
    no curvature from dividing by ~0, the pilot drives straight on."""
    pilot = PathPilot(((0.0, 0.0), (0.0, 10.0)), speed_mps=1.0, width_m=0.5, lookahead_m=1e-7)
    assert pilot.step(Pose(0.0, 5.0, NORTH)) == (1.0, 1.0)


def test_a_path_of_300_waypoints_is_flown_to_its_last_leg() -> None:
    """Segment indices past 256 (no longer small cached ints) end the look-ahead's advance as the first ones do."""
    pilot = PathPilot([(0.0, 0.1 * i) for i in range(300)], speed_mps=1.0, width_m=0.5, lookahead_m=1.0)
    assert pilot.step(Pose(0.0, 29.2, NORTH)) == (1.0, 1.0)  # on segment 292, the end 0.7 m ahead
    assert pilot._seg == 298
    assert pilot.step(Pose(0.0, 29.5, NORTH)) == (0.0, 0.0)
    assert pilot.finished


def _fly(path, speed_mps: float, turn_rate_rps: float, limit_s: float) -> tuple[PathPilot, float, float, Pose]:
    """Fly the leader alone (world/kinematics.py): the pilot, its time to the end, its largest cross-track error,
    its last pose."""
    pilot = PathPilot(path, speed_mps=speed_mps, width_m=0.5, max_turn_rate_rps=turn_rate_rps)
    pose = Pose(float(path[0][0]), float(path[0][1]), math.atan2(path[1][1] - path[0][1], path[1][0] - path[0][0]))
    worst, ticks = 0.0, 0
    while ticks * 0.05 < limit_s:
        left, right = pilot.step(pose)
        if pilot.finished:
            break
        pose = step(pose, left, right, 0.5, 0.05)
        ticks += 1
        worst = max(worst, _cross_track(path, pose))
    return pilot, ticks * 0.05, worst, pose


def _cross_track(path, pose: Pose) -> float:
    best = math.inf
    for (ax, ay), (bx, by) in zip(path[:-1], path[1:], strict=True):
        dx, dy = bx - ax, by - ay
        t = max(0.0, min(1.0, ((pose.x_m - ax) * dx + (pose.y_m - ay) * dy) / (dx * dx + dy * dy)))
        best = min(best, math.hypot(ax + t * dx - pose.x_m, ay + t * dy - pose.y_m))
    return best


SPEEDS_MPS = (0.5, 0.75, 1.0, 1.25, 1.5, 1.6, 1.75, 2.0, 2.25, 2.5)
TURN_RATES_RPS = (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5)


@pytest.mark.parametrize("speed", SPEEDS_MPS)
@pytest.mark.parametrize("turn_rate", TURN_RATES_RPS)
def test_the_leader_finishes_the_paper_path_at_any_speed_and_turn_rate(speed: float, turn_rate: float) -> None:
    # Before, it circled for ever in 24 of the 48 cases of 1.0-2.5 m/s and 0.15-0.5 rad/s (from 1.6 m/s at
    # 0.25 rad/s, 1.25 m/s at 0.2 rad/s).
    radius = speed / turn_rate
    corners = len(PAPER_TURNING_PATH) - 2
    # The path at the cruise speed, and at worst a full circle at each corner.
    bound_s = 60.0 / speed + corners * 2.0 * math.pi / turn_rate
    pilot, took_s, worst_m, pilot_end = _fly(PAPER_TURNING_PATH, speed, turn_rate, 2.0 * bound_s)
    assert pilot.finished
    assert took_s <= bound_s
    assert worst_m <= 2.0 * radius + pilot.lookahead_m  # measured: at most 1.73 R (2.5 m/s, 0.15 rad/s)
    # Steering wide it ends where it passes the last waypoint, which may lie inside its turning circle:
    # measured up to 1.30 R from it (R = 10 m) on paths the loader takes, 1.73 R on the others; else within 0.5 m.
    end_m = math.hypot(pilot_end[0] - 20.0, pilot_end[1] - 40.0)
    assert end_m <= (2.0 * radius if pilot.wide else 0.5 * pilot.lookahead_m)


def test_where_the_plain_pursuit_finished_the_leader_flies_it_unchanged() -> None:
    # 1.5 m/s at 0.25 rad/s, the shipped scenarios: the overshoot of the late turn, and no wide steering.
    pilot, took_s, worst_m, _ = _fly(PAPER_TURNING_PATH, 1.5, 0.25, 100.0)
    assert pilot.finished
    assert not pilot.wide
    assert took_s == pytest.approx(44.95)
    assert worst_m == pytest.approx(5.05, abs=0.01)


def test_a_leader_that_would_circle_steers_wide_and_finishes() -> None:
    pilot, took_s, _, _ = _fly(PAPER_TURNING_PATH, 1.6, 0.25, 200.0)
    assert pilot.finished  # passes the second corner >1 m away, moves on since it passed it
    assert not pilot.wide
    assert took_s == pytest.approx(44.3)
    pilot, took_s, _, _ = _fly(PAPER_TURNING_PATH, 1.75, 0.25, 200.0)
    assert pilot.finished  # circled its end point before
    assert pilot.wide
    assert took_s == pytest.approx(69.6)


def test_turn_room_says_which_segment_is_too_short() -> None:
    # 90 deg corners take R tan(45 deg) = R from each side; the middle segment (20 m) holds two.
    assert turn_room(PAPER_TURNING_PATH, 10.0) == []
    # The middle segment, 20 m long, and its two corners' 12.5 m each (the loader's error says it in words).
    assert no_room(PAPER_TURNING_PATH, 12.5) == [NoRoom((0.0, 20.0), (20.0, 20.0), 20.0, pytest.approx(25.0))]
    assert len(turn_room(PAPER_TURNING_PATH, 12.5)) == 1
    assert turn_room(((0.0, 0.0), (0.0, 5.0), (0.0, 0.0)), 1.0) == [
        "the path reverses at (0.0, 5.0): no turn circle fits a 180 deg turn"
    ]
    assert turn_room(((0.0, 0.0), (0.0, 50.0)), 100.0) == []


def _length(path) -> float:
    return sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(path[:-1], path[1:], strict=True))


@pytest.mark.parametrize("speed", SPEEDS_MPS)
@pytest.mark.parametrize("turn_rate", TURN_RATES_RPS)
def test_on_arcs_the_leader_flies_every_path_the_loader_takes(speed: float, turn_rate: float) -> None:
    radius = speed / turn_rate
    if turn_room(PAPER_TURNING_PATH, radius):
        # The middle 20 m segment holds two 90 deg corners up to R = 10 m: 14 of the 70 cases are refused.
        assert radius > 10.0
        with pytest.raises(ValueError, match="corners = 'arcs': segment"):
            PathPilot(PAPER_TURNING_PATH, speed, 0.5, max_turn_rate_rps=turn_rate, corners="arcs")
        return
    rounded = round_corners(PAPER_TURNING_PATH, radius)
    pilot = PathPilot(PAPER_TURNING_PATH, speed, 0.5, max_turn_rate_rps=turn_rate, corners="arcs")
    pose = Pose(0.0, 0.0, NORTH)
    ticks, off_arcs, off_corners = 0, 0.0, 0.0
    while ticks < 4000:
        left, right = pilot.step(pose)
        if pilot.finished:
            break
        pose = step(pose, left, right, 0.5, 0.05)
        ticks += 1
        off_arcs = max(off_arcs, _cross_track(rounded, pose))
        off_corners = max(off_corners, _cross_track(PAPER_TURNING_PATH, pose))
    assert pilot.finished
    assert not pilot.wide
    assert math.hypot(pose.x_m - 20.0, pose.y_m - 40.0) < 0.5
    # The rounded path at the cruise speed; measured: 0.53 s sooner (it stops 0.5 m short) to 0.03 s later.
    assert ticks * 0.05 <= _length(rounded) / speed + 0.5
    # Measured: 0.07-0.10 m off the arcs, 0.44-0.48 m at R = 10 m where the two arcs meet with no straight.
    assert off_arcs <= 0.5
    assert off_corners <= radius * (1.0 - math.cos(math.pi / 4)) + 0.5  # the arc's middle, inside each corner


def test_round_corners_puts_each_arc_on_its_circle_tangent_to_both_segments() -> None:
    pts = round_corners(PAPER_TURNING_PATH, 6.0)
    first = [p for p in pts if p[1] <= 20.0 and p[0] <= 6.0 and p[1] >= 14.0]
    assert first[0] == pytest.approx((0.0, 14.0))  # R tan(45 deg) = 6 m before the corner
    assert first[-1] == pytest.approx((6.0, 20.0))  # and 6 m after it
    assert max(abs(math.hypot(x - 6.0, y - 14.0) - 6.0) for x, y in first) < 1e-12  # on the circle about (6, 14)
    assert pts[-1] == (20.0, 40.0)
    assert max(math.dist(a, b) for a, b in zip(pts[1:-2], pts[2:-1], strict=True)) <= 8.0  # only straights are long
    with pytest.raises(ValueError, match="corners must be one of 'pursuit', 'arcs', got 'round'"):
        PathPilot(PAPER_TURNING_PATH, 1.5, 0.5, corners="round")
