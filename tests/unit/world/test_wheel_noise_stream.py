"""Wheel noise's random stream does not depend on the run's course
(docs/faults.md, "Random draws": one generator per robot, and per
wheel_noise fault, drawing the same amount on every tick whatever is
commanded). A robot whose agent is frozen stands still for a while; its
noise after the thaw, and every other robot's all along, are the draws they
would have had without the freeze.

Driven through the world's tick (world.tick) as its process drives it in
lockstep, with a real freeze from the fault schedule; every agent answers
each observation with the same command, so the runs differ by the freeze
alone."""

from __future__ import annotations

import pytest

from formation_swarm.protocol.messages import Command
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.kinematics import Pose, wrap_angle
from formation_swarm.world.tick import WorldTick

FREEZE = "freeze agent-2@2s for=2s"  # ticks 40-79; robot 2 stops once its command is stale (0.5 s)
THAWED = 90  # a tick by which robot 2 answers again
TICKS = 160
NOISE = {"scenario": ({"robot.wheel_noise_mps": 0.1}, []), "fault": ({}, ["wheel_noise *@0s sigma_mps=0.1"])}


def _fly(source: str, freeze: bool) -> dict[int, list[Pose]]:
    """Every robot's pose after each tick of fig11_obstacles, every agent commanding (1, 1.2) m/s."""
    overrides, faults = NOISE[source]
    sc = scenario_mod.load("fig11_obstacles", overrides, [*faults, *([FREEZE] if freeze else [])])
    world = WorldTick(sc, 1, lockstep=True, wall_s=lambda: 0.0)
    world.start(0.0)
    seqs = dict.fromkeys(sc.robots, 0)
    track: dict[int, list[Pose]] = {rid: [] for rid in sc.robots}
    while world.engine.tick < TICKS:
        for call in world.calls_due():
            world.apply_call(call)
        for rid, obs in world.observations():  # a frozen agent gets none, and answers none
            seqs[rid] += 1
            cmd = Command(
                sender=rid, seq=seqs[rid], tick=obs.tick, left_mps=1.0, right_mps=1.2, formation=0, done=False
            )
            world.command(cmd)
        world.close()
        world.step()
        for rid, r in world.engine.robots.items():
            track[rid].append(r.pose)
    return track


def _turns(poses: list[Pose]) -> list[float]:
    """The heading change of each tick, rad: with the same command it is the wheels' noise alone."""
    return [wrap_angle(b.theta_rad - a.theta_rad) for a, b in zip(poses, poses[1:], strict=False)]


@pytest.mark.parametrize("source", list(NOISE))
def test_a_freeze_shifts_no_robots_wheel_noise(source: str) -> None:
    frozen, free = _fly(source, freeze=True), _fly(source, freeze=False)
    assert frozen[2][50] == frozen[2][70] != free[2][70]  # robot 2 stood still, stopped as stale
    for rid in (1, 3):  # the others fly as without the freeze, bit for bit
        assert frozen[rid] == free[rid], rid
    # Robot 2's noise after the thaw is the very draw it had without the freeze.
    after = slice(THAWED, TICKS)
    assert _turns(frozen[2][after]) == pytest.approx(_turns(free[2][after]), abs=1e-12)
    assert max(abs(t - 0.02) for t in _turns(free[2][after])) > 1e-3  # the noise is there (0.2 m/s / 0.5 m * 0.05 s)
