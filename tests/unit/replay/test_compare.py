"""Recorded and replayed commands side by side (replay.compare), and the lines
swarm replay prints from them (replay.cli.report)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from formation_swarm.protocol.messages import Command
from formation_swarm.replay.cli import Job, report
from formation_swarm.replay.compare import Difference, compare
from formation_swarm.replay.feed import Inputs, Replayed
from formation_swarm.replay.wire import Wire
from formation_swarm.spec import scenario as scenario_mod


def cmd(tick: int, left: float, right: float, **kw: object) -> Command:
    fields = {"sender": 2, "seq": 2 * tick + 1, "tick": tick, "formation": 0, "done": False, **kw}
    return Command(left_mps=left, right_mps=right, **fields)  # type: ignore[arg-type]


RECORDED = {k: cmd(k, 1.0 + 0.01 * k, 1.2) for k in range(10)}


def test_the_same_commands_are_identical_to_the_bit() -> None:
    same = {k: dataclasses.replace(c) for k, c in RECORDED.items()}
    got = compare(RECORDED, same)
    assert (got.ticks, got.differing, got.first, got.identical) == (10, 0, None, True)
    assert (got.rms_left_mps, got.rms_right_mps, got.max_mps, got.max_tick) == (0.0, 0.0, 0.0, 0)


def test_the_first_difference_is_named_with_both_commands_and_the_wheels_rms() -> None:
    replayed = dict(RECORDED)
    replayed[4] = cmd(4, 1.04 + 1e-15, 1.2)  # one ulp or so: differs
    replayed[7] = cmd(7, 1.07, 1.2 + 0.3)
    got = compare(RECORDED, replayed)
    assert (got.ticks, got.differing, got.identical) == (10, 2, False)
    assert got.first == Difference(4, RECORDED[4], replayed[4])
    assert math.isclose(got.rms_right_mps, math.sqrt(0.3**2 / 10))
    assert got.rms_left_mps is not None
    assert got.rms_left_mps < 1e-14
    assert (round(got.max_mps, 12), got.max_tick) == (0.3, 7)


def test_a_tick_the_replay_left_unanswered_differs_and_other_fields_count_too() -> None:
    replayed = {k: c for k, c in RECORDED.items() if k != 0}
    replayed[3] = dataclasses.replace(RECORDED[3], formation=1)
    replayed[5] = dataclasses.replace(RECORDED[5], seq=99)
    got = compare(RECORDED, replayed)
    assert (got.differing, got.first) == (3, Difference(0, RECORDED[0], None))
    assert (got.rms_left_mps, got.rms_right_mps) == (0.0, 0.0)  # over the 9 ticks both answered
    assert compare(RECORDED, {}).rms_left_mps is None


def _job(what_if: tuple[str, ...] = (), restarted_at: int | None = None) -> Job:
    sc = scenario_mod.load("fig11_obstacles")
    inputs = Inputs(robot_id=2, inbox=[], recorded=RECORDED, restarted_at=restarted_at)
    return Job(Path("run"), Wire(Path("run/wire.mcap"), {"run_id": "r"}), sc, 1, inputs, what_if)


def test_the_lines_it_prints() -> None:
    """The words of both shapes (the other tests assert the records behind them)."""
    same = report(_job(), Replayed(commands=RECORDED), compare(RECORDED, RECORDED))
    replayed = {**RECORDED, 6: cmd(6, 0.5, 1.2)}
    lines = report(_job(("controller.law=lpsi",), restarted_at=10), Replayed(), compare(RECORDED, replayed))
    assert (same, lines) == (
        ["robot 2: identical over 10 ticks"],
        [
            "robot 2: differs at tick 6 (t = 0.30 s), 1 of 10 ticks differ",
            "  recorded: left 1.06 m/s, right 1.2 m/s, formation 0, done False, seq 13",
            "  replayed: left 0.5 m/s, right 1.2 m/s, formation 0, done False, seq 13",
            "  RMS difference of the wheel speeds: left 0.1771 m/s, right 0 m/s; largest 0.56 m/s at tick 6",
            "  its agent was restarted at tick 10: replayed up to there",
        ],
    )
