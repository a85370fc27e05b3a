"""A role's step times (agents.step_times): the median of its histogram, the
longest step and its tick, the steps over the tick, the call under way; and
the follower's first slow step said in its notes."""

from __future__ import annotations

import time

import pytest

from formation_swarm import FollowerInput, FollowerOutput
from formation_swarm.agents.step_times import StepTimes
from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS
from tests.helpers.fakes import observation

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")


def test_the_median_is_its_bins_mean_and_the_longest_step_keeps_its_tick() -> None:
    times = StepTimes(tick_s=0.05)
    assert (times.median_s(), times.stats()["max_s"]) == (None, None)
    for tick, took_s in enumerate([0.00105] * 5 + [0.0011] + [2.5] * 3):
        times.add(tick, took_s)
    st = times.stats()
    # 9 steps: the 5th is the median; 1.05 and 1.1 ms share a bin (9% wide), whose mean it says.
    assert st["median_s"] == pytest.approx((5 * 0.00105 + 0.0011) / 6)
    assert (st["steps"], st["max_s"], st["max_tick"], st["over_tick"], st["tick_s"]) == (9, 2.5, 6, 3, 0.05)


def test_a_call_under_way_is_seen_and_neither_a_prepare_nor_a_frozen_step_is_counted() -> None:
    times = StepTimes(tick_s=0.05)
    times.start(7, "prepare")
    call = times.in_call()
    assert call is not None
    assert (call["tick"], call["call"], call["for_s"] >= 0.0) == (7, "prepare", True)
    times.stop(counted=False)
    assert (times.in_call(), times.steps) == (None, 0)
    times.start(8)
    times.stop()
    assert (times.steps, times.max_tick) == (1, 8)
    times.continued()  # a freeze between two calls: nothing to leave out
    times.start(9)
    times.continued()  # a freeze during the call: its time holds the freeze
    assert (times.stop(), times.steps) == (None, 1)
    times.start(10)
    assert (times.stop() is not None, times.steps) == (True, 2)


class Sleepy:
    """A controller whose step takes ``sleep_s``, asleep or (``spin``) computing."""

    def __init__(self, sleep_s: float, spin: bool = False) -> None:
        self.sleep_s, self.spin = sleep_s, spin

    def step(self, inp: FollowerInput) -> FollowerOutput:
        if self.spin:
            end = time.thread_time() + self.sleep_s
            while time.thread_time() < end:
                pass
        else:
            time.sleep(self.sleep_s)
        return FollowerOutput(left_mps=0.0, right_mps=0.0)


def test_a_followers_first_step_computing_over_the_tick_is_noted_once() -> None:
    role = role_for(FIG11, 2, seed=1, controller=Sleepy(0.06, spin=True))  # the tick: 0.05 s
    for tick in range(3):
        role.take_observation(observation(tick))
        assert role.answer() is not None
    st = role.stats()["step_time"]
    assert (st["steps"], st["over_tick"], st["max_s"] > 0.06) == (3, 3, True)
    [note] = [n for n in role.notes if "longer than the tick" in n]
    assert note.startswith("controller fuzzy took ")  # the law its scenario names
    assert "s of CPU) in its step of tick 0, longer than the tick (0.05 s)" in note


def test_a_step_asleep_a_little_over_the_tick_is_counted_not_noted() -> None:
    """1.2 ticks asleep: as likely a busy machine's doing; 12 ticks: the controller's."""
    role = role_for(FIG11, 2, seed=1, controller=Sleepy(0.06))
    role.take_observation(observation(0))
    assert role.answer() is not None
    assert (role.stats()["step_time"]["over_tick"], [n for n in role.notes if "longer than the tick" in n]) == (1, [])
    role = role_for(FIG11, 2, seed=1, controller=Sleepy(0.6))
    role.take_observation(observation(0))
    assert role.answer() is not None
    [note] = [n for n in role.notes if "longer than the tick" in n]
    assert note.startswith("controller fuzzy took ")
    assert float(note.split()[3]) >= 0.6
