"""swarm.runtime.memory: a flood's memory is given back once, when it ends."""

from __future__ import annotations

import pytest

from formation_swarm.runtime import memory


def test_memory_is_given_back_once_after_a_flood_ends_and_never_without_one(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    monkeypatch.setattr(memory, "give_back", lambda: calls.append(1))
    relief = memory.FloodRelief(period_s=0.0, flood=500)
    assert [relief.check(n) for n in (0, 10, 20, 30)] == [False] * 4  # an honest run's few rejections
    assert relief.check(530) is False  # 500 in one look: a flood, still going
    assert relief.check(1100) is False
    assert relief.check(1110) is True  # the first quiet look after it
    assert relief.check(1120) is False
    assert (calls, relief.given_back) == ([1], 1)


def test_a_look_before_its_period_does_nothing() -> None:
    relief = memory.FloodRelief(period_s=3600.0)
    assert relief.check(10**6) is False
    assert relief.seen == 0


def test_giving_back_runs_where_glibc_is_and_where_it_is_not(monkeypatch: pytest.MonkeyPatch) -> None:
    memory.give_back()
    monkeypatch.setattr(memory, "_malloc_trim", lambda: None)
    memory.give_back()
