"""Lockstep robots whose answers stop while their token stays (world.stalls),
driven through the world's tick without Zenoh: stalled after
STALL_AFTER_MISSES deadlines missed in a row, no longer waited for until
they answer again; lost after a stall, awaited for LOST_WAIT_S."""

from __future__ import annotations

import re

from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.stalls import LOST_WAIT_S, STALL_AFTER_MISSES, STALLED_OBS_PERIOD_S
from formation_swarm.world.tick import WorldTick
from tests.helpers import SCENARIOS
from tests.helpers.messages import command

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")


class Wall:
    """The world's wall clock, set by the test."""

    def __init__(self) -> None:
        self.s = 0.0

    def __call__(self) -> float:
        return self.s


def _numbers(line: str) -> list[str]:
    """The numbers of a line the world prints, in order."""
    return re.findall(r"\d+(?:\.\d+)?", line)


def _world(wall: Wall) -> WorldTick:
    world = WorldTick(FIG11, FIG11.seed, lockstep=True, wall_s=wall)
    for rid in FIG11.robots:
        world.agent_token(rid, True)
    return world


def _answer(world: WorldTick, rid: int, seq: int, tick: int | None = None) -> None:
    tick = world.engine.tick if tick is None else tick
    world.command(command(sender=rid, seq=seq, tick=tick, left_mps=0.5, right_mps=0.5))


def _tick(world: WorldTick, answering: tuple[int, ...], seq: int) -> tuple[list[int], list[str]]:
    """One tick as the clock drives it: observations, the answers of
    ``answering``, the deadline for the rest; who was waited for at the
    deadline and the lines said."""
    world.start(0.0)
    dict(world.observations())
    for rid in answering:
        _answer(world, rid, seq)
    waiting = world.waiting()
    said: list[str] = []
    if waiting:
        world.miss(waiting)
        said = world.stall(waiting)
    world.close()
    world.step()
    return waiting, said


def test_a_robot_that_misses_its_deadlines_in_a_row_is_stalled_then_not_waited_for() -> None:
    world = _world(Wall())
    for n in range(1, STALL_AFTER_MISSES + 1):
        waiting, said = _tick(world, (1, 3), seq=n)
        assert waiting == [2]
        assert said == (
            []
            if n < STALL_AFTER_MISSES
            else [
                f"robot 2 stalled at t={(n - 1) * FIG11.dt_s:.2f} s: {STALL_AFTER_MISSES} deadlines missed in a row; "
                "stopped and not waited for until it answers again"
            ]
        )
    assert world.misses == STALL_AFTER_MISSES
    for n in range(STALL_AFTER_MISSES + 1, STALL_AFTER_MISSES + 50):
        waiting, _ = _tick(world, (1, 3), seq=n)
        assert waiting == []  # the tick ends once the others answered: no deadline waited
    assert world.misses == STALL_AFTER_MISSES
    assert world.engine.robots[2].command == (0.0, 0.0)  # stopped
    assert [e["event"] for e in world.stalls.events] == ["stalled"]
    assert world.stalls.events[0]["tick"] == STALL_AFTER_MISSES - 1


def test_a_stalled_robot_that_answers_again_is_waited_for_again() -> None:
    world = _world(Wall())
    for n in range(1, STALL_AFTER_MISSES + 2):
        _tick(world, (1, 3), seq=n)
    _answer(world, 2, seq=1, tick=world.engine.tick - 1)  # late, for a past tick: it is alive
    assert world.late_answers == 1
    waiting, _ = _tick(world, (1, 3), seq=100)
    assert waiting == [2]  # waited for, and missed, again
    assert [e["event"] for e in world.stalls.events] == ["stalled", "answering again"]


def test_misses_not_in_a_row_stall_no_one() -> None:
    world = _world(Wall())
    for n in range(1, 4 * STALL_AFTER_MISSES):
        _tick(world, (1, 2, 3) if n % STALL_AFTER_MISSES == 0 else (1, 3), seq=n)
    assert world.stalls.events == []
    assert world.misses == 4 * STALL_AFTER_MISSES - 1 - (4 * STALL_AFTER_MISSES - 1) // STALL_AFTER_MISSES


def test_while_every_robot_is_stalled_the_world_waits_for_them_all() -> None:
    world = _world(Wall())
    for n in range(1, STALL_AFTER_MISSES + 1):
        _tick(world, (), seq=n)
    assert world.stalls.stalled == {1, 2, 3}
    waiting, _ = _tick(world, (), seq=10)
    assert waiting == [1, 2, 3]  # nothing would move without them: each tick waits its deadline
    waiting, _ = _tick(world, (1,), seq=11)
    assert waiting == []  # one answers: the stalled others are not waited for


def test_a_robot_lost_after_a_stall_is_awaited_until_readmitted_or_its_wait_ends() -> None:
    wall = Wall()
    world = _world(wall)
    for n in range(1, STALL_AFTER_MISSES + 1):
        _tick(world, (1,), seq=n)
    wall.s = 10.0  # the session's lease ends
    lost = world.agent_token(2, False)
    assert _numbers(lost) == ["2", f"{STALL_AFTER_MISSES * FIG11.dt_s:.2f}", f"{LOST_WAIT_S:g}"]  # who, when, wait
    assert "; it had stalled: " in lost
    assert lost.endswith("(the clock holds)")
    assert world.awaited() == [2]
    assert world.agent_token(3, False).endswith("(the clock holds)")
    assert world.awaited() == [2, 3]
    world.agent_token(2, True)  # the link is back: a fresh token
    assert world.readmit(hears=lambda rid: True) == [2]
    assert world.awaited() == [3]
    wall.s = 10.0 + LOST_WAIT_S - 0.1
    assert world.overdue() == []
    wall.s = 10.0 + LOST_WAIT_S
    (late,) = world.overdue()
    assert _numbers(late) == ["3", f"{LOST_WAIT_S:g}"]  # the robot, its wait
    assert late.endswith("; the run goes on without it")
    assert world.awaited() == []
    events = [(e["robot"], e["event"]) for e in world.stalls.events]
    assert events == [
        (2, "stalled"),
        (3, "stalled"),
        (2, "lost while stalled"),
        (3, "lost while stalled"),
        (3, "not back in time"),
    ]


def test_a_robot_whose_token_goes_while_it_answers_is_not_awaited() -> None:
    world = _world(Wall())
    _tick(world, (1, 2, 3), seq=1)
    lost = world.agent_token(2, False)
    assert _numbers(lost) == ["2", "0.05"]
    assert "stalled" not in lost
    assert world.awaited() == []


def test_a_stalled_robot_is_observed_only_now_and_then() -> None:
    wall = Wall()
    world = _world(wall)
    for n in range(1, STALL_AFTER_MISSES + 1):
        _tick(world, (1, 3), seq=n)
    seen = []
    for n in range(10):
        wall.s = n * STALLED_OBS_PERIOD_S / 5
        world.start(0.0)
        seen.append(2 in dict(world.observations()))
        for rid in (1, 3):
            _answer(world, rid, seq=100 + n)
        world.close()
        world.step()
    assert seen == [True, False, False, False, False, True, False, False, False, False]
