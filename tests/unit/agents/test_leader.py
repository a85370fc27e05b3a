"""The leader's formation decision and how often it repeats the code."""

from __future__ import annotations

import pytest

from formation_swarm.agents.leader import CodeRepeats, FormationSwitch


def test_switch_flies_line_near_obstacles_and_back_after_clear_time() -> None:
    sw = FormationSwitch(normal_code=0, avoid_code=1, clear_after_s=1.0, dt_s=0.1)
    assert [sw.step([]) for _ in range(3)] == [0, 0, 0]
    assert sw.step(["rock"]) == 1
    codes = [sw.step([]) for _ in range(12)]
    assert codes == [1] * 9 + [0] * 3  # back after 10 clear ticks = 1.0 s
    assert FormationSwitch(0, None, 1.0, 0.1).step(["rock"]) == 0  # no avoidance formation: stays


def test_repeats_every_tick_after_a_change_then_on_the_heartbeat() -> None:
    rep = CodeRepeats(burst_s=0.5, period_s=0.3, dt_s=0.1)
    codes = [0] * 12 + [1] * 10
    sent = [t for t, c in enumerate(codes) if rep.due(c)]
    # Start: ticks 0-5 (burst of 5 ticks after the first), then every 3 ticks: 8, 11.
    # Change at 12: 12-17, then 20.
    assert sent == [0, 1, 2, 3, 4, 5, 8, 11, 12, 13, 14, 15, 16, 17, 20]


def test_zero_burst_is_heartbeat_only() -> None:
    rep = CodeRepeats(burst_s=0.0, period_s=0.2, dt_s=0.1)
    assert [t for t in range(7) if rep.due(0)] == [0, 2, 4, 6]


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"burst_s": -1.0, "period_s": 0.5, "dt_s": 0.05}, "code_burst_s"),
        ({"burst_s": 1.0, "period_s": 0.0, "dt_s": 0.05}, "code_period_s"),
        ({"burst_s": 1.0, "period_s": float("nan"), "dt_s": 0.05}, "code_period_s"),
    ],
)
def test_bad_repeat_parameters_name_themselves(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        CodeRepeats(**kwargs)


def test_a_period_of_one_tick_or_less_repeats_every_tick() -> None:
    for period_s in (0.1, 0.01):  # one tick; under half a tick (rounds to 0, held at 1)
        rep = CodeRepeats(burst_s=0.0, period_s=period_s, dt_s=0.1)
        assert [t for t in range(5) if rep.due(0)] == [0, 1, 2, 3, 4]


def test_a_change_restarts_the_burst_even_back_to_an_earlier_code() -> None:
    rep = CodeRepeats(burst_s=0.2, period_s=1.0, dt_s=0.1)
    codes = [0] * 5 + [1] * 5 + [0] * 5
    assert [t for t, c in enumerate(codes) if rep.due(c)] == [0, 1, 2, 5, 6, 7, 10, 11, 12]


def test_switch_needs_clear_after_s_of_clear_sensing_in_a_row() -> None:
    sw = FormationSwitch(normal_code=1, avoid_code=0, clear_after_s=0.3, dt_s=0.1)
    assert sw.step(["rock"]) == 0
    assert [sw.step([]) for _ in range(2)] == [0, 0]
    assert sw.step(["rock"]) == 0  # seen again: the clear time starts over
    assert [sw.step([]) for _ in range(4)] == [0, 0, 1, 1]
