"""Link faults: a drop is a function of (seed, link, sequence number) and of
nothing else, so a run with drops is as reproducible as one without."""

from __future__ import annotations

import random

import pytest

from formation_swarm.protocol.links import Link, link_name, uniform


def test_link_names() -> None:
    assert link_name("formation", 1, 3) == "formation:1>3"
    assert link_name("obs", 0, 2) == "obs:0>2"


def test_uniform_is_pinned() -> None:
    """Which messages drop decides the 10% and 30% columns of docs/results.md:
    the function must not change unnoticed."""
    assert uniform(0, "obs:0>2", 1) == pytest.approx(0.9076628032801277, abs=1e-15)
    assert uniform(0, "obs:0>2", 2) == pytest.approx(0.03620079366543912, abs=1e-15)
    assert uniform(1, "obs:0>2", 1) == pytest.approx(0.057878479059083054, abs=1e-15)
    assert uniform(0, "obs:0>3", 1) == pytest.approx(0.1634588332782438, abs=1e-15)
    assert uniform(-5, "x", 3) == uniform(-5, "x", 2**64 + 3)  # seq modulo 2**64


def test_uniform_is_uniform() -> None:
    draws = [uniform(7, "cmd:2>0", s) for s in range(20_000)]
    assert all(0.0 <= u < 1.0 for u in draws)
    assert sum(draws) / len(draws) == pytest.approx(0.5, abs=0.01)
    assert 0.28 < sum(u < 0.3 for u in draws) / len(draws) < 0.32  # 0.290 here


def test_drops_depend_on_seed_link_and_seq_only() -> None:
    """The same decisions from two links built alike, whatever the order the
    messages come in and whatever else draws random numbers meanwhile."""
    seqs = list(range(1, 2001))
    a = Link("obs:0>2", 0.3, seed=0)
    dropped_a = {s for s in seqs if not a.accept(s)}
    shuffled = list(seqs)
    random.Random(1).shuffle(shuffled)
    b = Link("obs:0>2", 0.3, seed=0)
    dropped_b = set()
    for s in shuffled:
        random.random()  # other draws in between change nothing
        if not b.accept(s):
            dropped_b.add(s)
    assert dropped_a == dropped_b
    assert dropped_a == {s for s in seqs if uniform(0, "obs:0>2", s) < 0.3}
    assert {s for s in range(1, 41) if s in dropped_a} == {2, 4, 6, 11, 12, 14, 15, 16, 20, 21, 22, 23, 25, 29, 30}
    assert (a.received, a.dropped) == (2000, len(dropped_a))
    assert 0.27 < a.dropped / a.received < 0.33
    other_seed = Link("obs:0>2", 0.3, seed=1)
    other_link = Link("obs:0>3", 0.3, seed=0)
    assert {s for s in seqs if not other_seed.accept(s)} != dropped_a
    assert {s for s in seqs if not other_link.accept(s)} != dropped_a


def test_no_drops_at_zero_and_all_at_one() -> None:
    never, always = Link("x", 0.0, 3), Link("x", 1.0, 3)
    assert all(never.accept(s) for s in range(500))
    assert not any(always.accept(s) for s in range(500))
    assert (never.received, never.dropped, always.received, always.dropped) == (500, 0, 500, 500)


@pytest.mark.parametrize("p", [-0.1, 1.5, float("nan")])
def test_a_drop_probability_outside_0_1_names_the_link(p: float) -> None:
    with pytest.raises(ValueError, match="obs:0>2"):
        Link("obs:0>2", p, 0)
