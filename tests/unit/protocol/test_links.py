"""Link faults: a drop is a function of (seed, link, sequence number) and of
nothing else, so a run with drops is as reproducible as one without; the
faults of the schedule (drop, burst, delay, duplicate, reorder, partition)
are placed on the message's tick and draw from (seed, link, seq, fault index)."""

from __future__ import annotations

import collections
import dataclasses
import math
import random

import pytest

from formation_swarm.common.faults import Fault
from formation_swarm.protocol.links import Link, fault_key, fault_uniform, faults_on, link_name, uniform, whole_ticks


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


# -- link faults: every behaviour with its numbers ---------------------------------

DT = 0.05  # 20 Hz


def faulty(*faults: str, name: str = "obs:0>2", seed: int = 0, robot: int = 2, cls: str = "obs") -> Link:
    schedule = tuple(Fault.parse(f) for f in faults)
    return Link(name, 0.0, seed, faults_on(schedule, cls, robot), DT)


def run(link: Link, ticks: range) -> list[list[int]]:
    """One message per tick, seq = tick + 1 (as the world numbers observations), item = tick."""
    return [link.deliver(t + 1, t, t) for t in ticks]


def test_faults_on_keeps_the_schedule_index_and_the_links_own_faults() -> None:
    schedule = tuple(
        Fault.parse(f)
        for f in (
            "drop obs:2@1s p=0.1",
            "drop cmd:2@1s p=0.1",
            "delay links:*@1s ticks=1",
            "partition 2@2s for=1s from=world",
            "partition 2@2s for=1s from=leader",
            "reorder formation:3@1s p=0.1",
        )
    )
    assert [i for i, _ in faults_on(schedule, "obs", 2)] == [0, 2, 3]
    assert [i for i, _ in faults_on(schedule, "cmd", 2)] == [1, 2, 3]
    assert [i for i, _ in faults_on(schedule, "formation", 2)] == [2, 4]
    assert [i for i, _ in faults_on(schedule, "formation", 3)] == [2, 5]
    assert faults_on(schedule, "obs", 3) == ((2, schedule[2]),)


def test_a_drop_fault_loses_its_share_in_its_window_only() -> None:
    link = faulty("drop obs:2@5s for=500s p=0.3")  # ticks 100 .. 10099
    out = run(link, range(10_200))
    lost = [t for t in range(10_200) if not out[t]]
    assert (min(lost), max(lost)) >= (100, 100)
    assert max(lost) < 10_100
    # Binomial(10_000, 0.3): 3000 +- 3 sigma (sigma = 45.8)
    assert abs(len(lost) - 3000) < 3 * math.sqrt(10_000 * 0.3 * 0.7)
    assert len(lost) == 2962  # pinned: which messages drop must not change unnoticed
    assert lost == [
        t
        for t in range(100, 10_100)
        if fault_uniform(0, "obs:0>2", t + 1, fault_key(Fault.parse("drop obs:2@5s for=500s p=0.3"))) < 0.3
    ]
    assert (link.received, link.dropped, link.lost) == (10_200, 2962, 2962)
    assert link.stats()["faults"] == {"0": {"dropped": 2962}}
    assert all(out[t] == [t] for t in range(10_200) if t not in set(lost))


def test_steady_drops_and_drop_faults_add_up_and_are_told_apart() -> None:
    schedule = (Fault.parse("drop obs:2@0s p=0.5"),)
    link = Link("obs:0>2", 0.2, 4, faults_on(schedule, "obs", 2), DT)
    run(link, range(4000))
    steady = sum(uniform(4, "obs:0>2", s) < 0.2 for s in range(1, 4001))
    assert link.dropped == 4000 - sum(
        uniform(4, "obs:0>2", s) >= 0.2
        and fault_uniform(4, "obs:0>2", s, fault_key(Fault.parse("drop obs:2@0s p=0.5"))) >= 0.5
        for s in range(1, 4001)
    )
    assert link.stats()["faults"]["0"]["dropped"] == link.dropped - steady  # the steady drop is no fault's
    assert 0.58 < link.dropped / 4000 < 0.62  # 1 - 0.8 * 0.5


def runs_of(lost: list[bool]) -> list[int]:
    out, n = [], 0
    for x in [*lost, False]:
        if x:
            n += 1
        elif n:
            out.append(n)
            n = 0
    return out


def test_bursts_are_a_gilbert_elliott_chain() -> None:
    """p_bad 0.05, p_good 0.3, loss 1: losses come in runs of mean length
    1 / p_good = 3.33 messages; the chain is bad, so a message lost, a share
    p_bad / (p_bad + p_good) = 14.3% of the time."""
    n = 50_000
    link = faulty("burst obs:2@0s p_bad=0.05 p_good=0.3")
    lost = [not got for got in run(link, range(n))]
    runs = runs_of(lost)
    assert sum(lost) == link.dropped == sum(runs)
    assert link.dropped / n == pytest.approx(0.05 / 0.35, abs=0.01)  # 0.1396 here
    # Geometric run lengths: mean 1/p_good, sd sqrt(1 - p_good)/p_good; ~2,000 runs
    mean, sd = 1 / 0.3, math.sqrt(0.7) / 0.3
    assert abs(sum(runs) / len(runs) - mean) < 3 * sd / math.sqrt(len(runs))
    assert len(runs) < link.dropped / 2  # bursts, not scattered losses
    # A drop fault of the same rate scatters its losses: runs of mean 1 / (1 - p) = 1.16
    scattered = runs_of([not got for got in run(faulty("drop obs:2@0s p=0.1396"), range(n))])
    assert sum(scattered) / len(scattered) < 1.25


def test_a_burst_with_partial_loss_and_its_draws() -> None:
    n = 40_000
    link = faulty("burst obs:2@0s p_bad=0.1 p_good=0.1 loss=0.5")
    lost = [not got for got in run(link, range(n))]
    assert sum(lost) / n == pytest.approx(0.5 * 0.5, abs=0.02)  # half the time bad, half of those lost
    # The chain by hand, from the pure draws: the same losses
    BURST = fault_key(Fault.parse("burst obs:2@0s p_bad=0.1 p_good=0.1 loss=0.5"))  # noqa: N806
    bad, expected = False, []
    for seq in range(1, n + 1):
        u = fault_uniform(0, "obs:0>2", seq, BURST, 0)
        bad = (u >= 0.1) if bad else (u < 0.1)
        expected.append(bad and fault_uniform(0, "obs:0>2", seq, BURST, 1) < 0.5)
    assert lost == expected


def test_a_delay_releases_at_tick_plus_d() -> None:
    link = faulty("delay obs:2@1s for=1s ticks=4")  # messages of ticks 20..39
    out = run(link, range(60))
    assert out[19] == [19]
    assert out[20:24] == [[], [], [], []]
    assert out[24] == [20]  # tick 20's message comes out with tick 24's arrival, before nothing else: 24 is held
    assert out[39] == [35]
    assert out[40] == [36, 40]  # the held ones first, then the first undelayed arrival
    assert out[41:44] == [[37, 41], [38, 42], [39, 43]]
    assert out[44] == [44]
    assert (link.delayed, link.held) == (20, 0)
    assert link.stats()["faults"] == {"0": {"delayed": 20}}


def test_held_messages_come_out_with_due_when_nothing_arrives() -> None:
    link = faulty("delay cmd:2@0s ticks=3", name="cmd:2>0", cls="cmd")
    assert link.deliver(1, 0, "a") == []
    assert link.deliver(2, 1, "b") == []
    assert link.due(2) == []
    assert link.held == 2
    assert link.due(3) == ["a"]
    assert link.due(3) == []
    assert link.due(10) == ["b"]
    assert link.held == 0


def test_a_delay_in_ms_is_rounded_up_to_whole_ticks() -> None:
    assert whole_ticks(100.0, "ms", 0.05) == 2
    assert whole_ticks(101.0, "ms", 0.05) == 3
    assert whole_ticks(100.02, "ms", 0.05) == 3  # a hair over two ticks of 50 ms
    assert whole_ticks(1.0, "ms", 0.05) == 1
    assert whole_ticks(0.0, "ms", 0.05) == 0
    assert whole_ticks(2.0, "ticks", 0.05) == 2
    assert whole_ticks(2.5, "ticks", 0.05) == 3
    assert whole_ticks(30.0, "ms", 0.01) == 3
    link = faulty("delay obs:2@0s ms=120")  # 2.4 ticks -> 3
    out = run(link, range(10))
    assert out[:3] == [[], [], []]
    assert out[3:] == [[t] for t in range(7)]


def test_jitter_is_uniform_within_d_and_d_plus_j() -> None:
    n = 6000
    link = faulty("delay obs:2@0s ticks=2 jitter_ticks=3")
    released: dict[int, int] = {}
    for t in range(n):
        for item in link.deliver(t + 1, t, t):
            released[item] = t
    link_due = link.due(n + 10)
    for item in link_due:
        released[item] = n + 10
    lateness = collections.Counter(released[t] - t for t in range(n - 10))
    assert set(lateness) == {2, 3, 4, 5}
    for d in (2, 3, 4, 5):
        assert abs(lateness[d] - (n - 10) / 4) < 3 * math.sqrt((n - 10) * 0.25 * 0.75), lateness
    # ms jitter: 80 ms at 20 Hz is 2 ticks
    ms = faulty("delay obs:2@0s ms=50 jitter_ms=80")
    late: set[int] = set()
    for t in range(400):
        late |= {t - item for item in ms.deliver(t + 1, t, t)}
    assert late == {1, 2, 3}


def test_duplicates_come_twice() -> None:
    link = faulty("duplicate obs:2@0s p=0.2")
    out = run(link, range(5000))
    twice = [t for t in range(5000) if out[t] == [t, t]]
    assert all(out[t] == [t] for t in range(5000) if t not in set(twice))
    assert twice == [
        t
        for t in range(5000)
        if fault_uniform(0, "obs:0>2", t + 1, fault_key(Fault.parse("duplicate obs:2@0s p=0.2"))) < 0.2
    ]
    assert link.duplicated == len(twice) == 1046
    assert abs(len(twice) - 1000) < 3 * math.sqrt(5000 * 0.2 * 0.8)


def test_a_reordered_message_comes_right_after_the_next() -> None:
    link = faulty("reorder obs:2@0s p=0.1")
    out = run(link, range(5000))
    held = [
        t
        for t in range(5000)
        if fault_uniform(0, "obs:0>2", t + 1, fault_key(Fault.parse("reorder obs:2@0s p=0.1"))) < 0.1
    ]
    assert link.reordered == len(held) == 458
    flat = [x for got in out for x in got]
    assert sorted(flat) + [4999] * link.held == list(range(5000))  # nothing lost, nothing twice (the last may wait)
    for t in held:
        assert out[t] == [] or out[t] == [t - 1]  # held (releasing a message held just before it)
        if t + 1 not in held and t + 1 < len(out):
            assert out[t + 1] == [t + 1, t]  # [next, held]
    assert out[held[0] + 1] == [held[0] + 1, held[0]]


def test_back_to_back_reorders_release_the_one_before() -> None:
    link = faulty("reorder obs:2@0s p=1")
    assert run(link, range(4)) == [[], [0], [1], [2]]
    assert link.held == 1


def test_a_partition_loses_everything_in_its_window_to_the_tick() -> None:
    link = faulty("partition 2@1s for=2s from=world")  # ticks 20..59
    out = run(link, range(100))
    assert (out[19], out[60]) == ([19], [60])
    assert all(out[t] == [] for t in range(20, 60))
    assert (link.partitioned, link.dropped, link.lost, link.received) == (40, 0, 40, 100)
    assert link.stats()["faults"] == {"0": {"partitioned": 40}}


def test_a_partition_also_takes_what_the_link_held() -> None:
    # Delayed by 5: tick 15..19's messages would come out at 20..24, inside the partition.
    link = faulty("delay obs:2@0s for=1s ticks=5", "partition 2@1s for=0.5s from=world")
    out = run(link, range(40))
    assert out[19] == [14]
    assert all(out[t] == [] for t in range(20, 30))
    assert out[30] == [30]
    assert link.partitioned == 10 + 5
    assert link.stats()["faults"] == {"0": {"delayed": 20}, "1": {"partitioned": 15}}
    reorder = faulty("reorder obs:2@0s p=1", "partition 2@1s for=1s from=world")
    got = run(reorder, range(45))
    assert (got[19], got[20], got[40]) == ([18], [], [])  # tick 19's, held, went with the partition
    assert (got[41], reorder.partitioned) == ([40], 21)


def test_two_links_alike_give_the_same_outputs_and_another_seed_does_not() -> None:
    schedule = (
        "burst obs:2@1s for=20s p_bad=0.05 p_good=0.3",
        "delay obs:2@2s for=10s ticks=2 jitter_ticks=2",
        "duplicate obs:2@0s p=0.2",
        "reorder obs:2@0s p=0.1",
        "drop obs:2@5s for=5s p=0.3",
        "partition 2@12s for=2s",
    )
    a, b, c = faulty(*schedule), faulty(*schedule), faulty(*schedule, seed=1)
    random.seed(99)
    out_a = run(a, range(600))
    random.random()  # other draws in between change nothing
    out_b = run(b, range(600))
    assert out_a == out_b
    assert a.stats() == b.stats()
    assert run(c, range(600)) != out_a
    assert a.stats() == {
        "received": 600,
        "dropped": 89,
        "partitioned": 44,  # 40 arrivals (ticks 240..279) and 4 messages held into the window
        "delayed": 147,
        "duplicated": 91,
        "reordered": 30,  # only what would come out now: a delayed message is not also reordered
        "held": 0,
        "faults": {
            "0": {"dropped": 55},
            "1": {"delayed": 147},
            "2": {"duplicated": 91},
            "3": {"reordered": 30},
            "4": {"dropped": 34},
            "5": {"partitioned": 44},
        },
    }


def test_accept_is_for_links_without_faults_and_faults_need_dt() -> None:
    with pytest.raises(ValueError, match="obs:0>2 has faults"):
        faulty("drop obs:2@0s p=0.1").accept(1)
    schedule = (Fault.parse("drop obs:2@0s p=0.1"),)
    with pytest.raises(ValueError, match="dt_s"):
        Link("obs:0>2", 0.0, 0, faults_on(schedule, "obs", 2))
    with pytest.raises(ValueError, match="not a link fault"):
        Link("obs:0>2", 0.0, 0, [(0, Fault.parse("kill agent-2@1s"))], DT)
    plain = Link("obs:0>2", 0.0, 0)
    assert plain.deliver(1, 0, "x") == ["x"]
    assert plain.stats() == {
        "received": 1,
        "dropped": 0,
        "partitioned": 0,
        "delayed": 0,
        "duplicated": 0,
        "reordered": 0,
        "held": 0,
    }


def test_a_faults_draws_do_not_depend_on_the_other_faults_of_the_schedule() -> None:
    """Adding a fault (here one that drops nothing, earlier in the schedule)
    changes none of the draws of the others; two identical faults draw apart."""
    drop = Fault.parse("drop obs:2@10s for=5s p=0.5")
    alone = Link("obs:0>2", 0.0, 7, faults_on((drop,), "obs", 2), DT)
    extra = (Fault.parse("drop obs:2@1s for=1s p=0"), drop)
    beside = Link("obs:0>2", 0.0, 7, faults_on(extra, "obs", 2), DT)
    assert run(alone, range(400)) == run(beside, range(400))
    assert alone.dropped == beside.dropped > 0
    twice = Link("obs:0>2", 0.0, 7, faults_on((drop, drop), "obs", 2), DT)
    assert list(twice.keys.values()) == [f"{drop}~0", f"{drop}~1"]


def test_a_links_rules_are_fixed_when_it_is_made() -> None:
    link: Link[int] = Link("obs:0>2", 0.0, 0, [(0, Fault.parse("drop obs:2@0s p=0.5"))], DT)
    (rule,) = link.rules
    with pytest.raises(dataclasses.FrozenInstanceError):
        rule.p = 0.0  # type: ignore[misc]
    assert (rule.kind, rule.start, rule.end, rule.p) == ("drop", 0, None, 0.5)


def test_messages_released_at_the_same_tick_come_in_their_order_of_arrival() -> None:
    link: Link[str] = Link("obs:0>2", 0.0, 0, [(0, Fault.parse("delay obs:2@0s ticks=2"))], DT)
    assert link.deliver(1, 0, "b") + link.deliver(2, 0, "a") + link.due(1) == []
    assert link.due(2) == ["b", "a"]  # not sorted by content
    assert (link.delayed, link.held) == (2, 0)
