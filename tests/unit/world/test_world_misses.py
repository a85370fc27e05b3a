"""Each robot's lockstep misses (world.misses), and those a scheduled kill,
restart, freeze or partition explains, counted as the world's tick counts
them: a miss outside every fault's window (and the second after it) is
the run's not reproducible."""

from __future__ import annotations

from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.misses import Misses
from formation_swarm.world.tick import WorldTick
from tests.helpers import SCENARIOS
from tests.helpers.messages import command

DT = 0.05


def _faults(*specs: str) -> tuple:
    return scenario_mod.load(SCENARIOS / "fig11_obstacles.toml", faults=specs).faults


def test_a_miss_outside_every_faults_window_and_its_second_after_is_unexplained() -> None:
    # freeze agent-2 ticks 20-29, then 20 ticks to settle; a partition of 3 ticks 40-59; a logger freeze: everyone's.
    misses = Misses(_faults("freeze agent-2@1s for=0.5s", "partition 3@2s for=1s", "freeze logger@5s for=1s"), DT)
    for tick in (19, 20, 29, 49, 50):
        misses.count(2, tick, returning=False)
    for tick in (39, 40, 59, 79, 80):
        misses.count(3, tick, returning=False)
    misses.count(1, 100, returning=False)  # the logger's freeze: ticks 100-119
    misses.count(1, 300, returning=True)  # just back from a fault
    assert misses.stats() == {
        "1": {"misses": 2, "by_faults": 2, "first_tick": None},
        "2": {"misses": 5, "by_faults": 3, "first_tick": 19},
        "3": {"misses": 5, "by_faults": 3, "first_tick": 39},
    }


def test_the_worlds_tick_counts_each_robots_misses_and_a_thawed_robots_first_as_its_freezes() -> None:
    sc = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml", faults=["freeze agent-2@20s for=1s"])
    world = WorldTick(sc, sc.seed, lockstep=True, wall_s=lambda: 0.0)
    world.start(0.0)
    dict(world.observations())
    world.command(command(sender=1, seq=1, tick=0, left_mps=0.0, right_mps=0.0))
    world.miss(world.waiting())  # 2 and 3 missed tick 0: no fault yet
    world.close()
    world.step()
    world.faults.thawing.add(2)  # as after its thaw: its first answer is the freeze's, whatever the tick
    world.start(0.0)
    dict(world.observations())
    world.miss([2])
    assert world.misses == 3
    assert world.robot_misses.stats() == {
        "2": {"misses": 2, "by_faults": 1, "first_tick": 0},
        "3": {"misses": 1, "by_faults": 0, "first_tick": 0},
    }
