"""Partition-zone collision avoidance (eq. 11-13) proven to matter: a formation
change that collides without it and keeps its clearance with it.

The closed loop is the world's own engine (kinematics, camera, metrics) with
the leader's pilot and the follower's brain, in one process: the same objects
the world and agent processes run, without the wire.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from formation_swarm.agents.follower import Follower
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.engine import WorldEngine
from formation_swarm.world.kinematics import Pose

# The follower flies slightly ahead of its leader on the right, then is told to
# take the slot on its left: the straight way there crosses the leader's bow.
SWAP_SIDES = """
[run]
name = "swap-sides"
robots = 2
duration_s = 20.0

[leader]
waypoints = [[0.0, 0.0], [0.0, 100.0]]
formation = "right"

[formations.right]
shape = "custom"
slots = { "2" = { reference = 1, offset = [1.5, 0.5] } }

[formations.left]
shape = "custom"
slots = { "2" = { reference = 1, offset = [-1.5, 0.0] } }

[controller]
vn = "dynamic"
clearance_m = 1.0
"""
CHANGE_AT_S = 8.0


def fly_the_change(tmp_path: Path, seed: int, avoidance: bool) -> dict:
    """The run's summary; the formation changes from "right" to "left" at CHANGE_AT_S."""
    path = tmp_path / "swap_sides.toml"
    path.write_text(SWAP_SIDES)
    sc = scenario_mod.load(path)
    eng = WorldEngine(sc, seed)
    ld = sc.leader
    pilot = PathPilot(ld.waypoints, ld.speed_mps, sc.width_m, ld.lookahead_m, ld.turn_rate_rps)
    follower = Follower(sc.followers[2], sc.formations["right"].slots[2].offset)
    code = sc.code_of("right")
    while eng.tick < sc.ticks:
        now = eng.time_s
        if now >= CHANGE_AT_S and code != sc.code_of("left"):
            code = sc.code_of("left")
            follower.set_offset(sc.formations["left"].slots[2].offset)
            if not avoidance:
                follower.changing = False  # straight to the new slot: eq. 13 skipped
        pose, _, _ = eng.observation(1)
        eng.set_command(1, *pilot.step(Pose(*pose)), code, now)
        _, readings, _ = eng.observation(2)
        reading = next(((rho, phi, beta) for rid, rho, phi, beta in readings if rid == 1), None)
        d = follower.step(reading)
        eng.set_command(2, d.left_mps, d.right_mps, code, now)
        eng.step(now)
    return eng.summary()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_swapping_sides_collides_without_avoidance_and_keeps_clear_with_it(tmp_path: Path, seed: int) -> None:
    """Measured (seeds 0-4, changes at 6-11 s): with eq. 13 the robots stay
    1.23-1.44 m apart, without it they touch (0.20-0.25 m, under the 0.4 m body)."""
    with_it = fly_the_change(tmp_path, seed, avoidance=True)
    without = fly_the_change(tmp_path, seed, avoidance=False)
    assert [e["formation"] for e in with_it["formation_events"]] == ["left", "left"]  # both robots changed
    assert with_it["collisions"] == 0
    assert with_it["min_distance_m"] > 1.0  # the clearance asked for (clearance_m)
    assert without["collisions"] >= 1
    assert without["min_distance_m"] < without["robot_diameter_m"]
    # Both end up on the new slot: the avoidance costs a detour, not the formation.
    assert with_it["final_poses"]["2"][0] < with_it["final_poses"]["1"][0] - 1.0  # left of a leader heading +y
