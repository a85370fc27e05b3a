"""A formation change that crosses the leader's bow, flown in one process: the
world's own engine with the leader's pilot and the follower's brain."""

from __future__ import annotations

from pathlib import Path

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
