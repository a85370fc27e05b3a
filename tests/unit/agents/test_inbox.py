"""An agent's checks beyond the schema (agents/inbox.py), message by message."""

from __future__ import annotations

import math

import pytest

from formation_swarm.agents.inbox import ANGLE_LIMIT_RAD, REPLAYED, TICK_AHEAD, InboxChecks
from formation_swarm.protocol.messages import WORLD_ID, FormationCode, Observation

RANGE_M, SIGMA_M, SENSING_M, DT_S = 10.0, 0.05, 6.0, 0.05


def checks() -> InboxChecks:
    return InboxChecks((1, 2, 3), RANGE_M, SIGMA_M, SENSING_M, DT_S)


def obs(tick: int, readings: tuple = ((1, 2.0, 0.1, 0.2),), obstacles: tuple = ()) -> Observation:
    return Observation(
        sender=WORLD_ID,
        seq=tick + 1,
        tick=tick,
        time_s=tick * DT_S,
        pose=(0.0, 0.0, 0.0),
        readings=readings,
        obstacles=obstacles,
    )


def test_observations_must_be_newer_than_the_last_taken() -> None:
    c = checks()
    assert c.observation(obs(5)) is None
    assert c.observation(obs(5)) == REPLAYED
    assert c.observation(obs(4)) == REPLAYED
    assert c.observation(obs(7)) is None  # a gap is fine: the agent may have missed some
    assert c.last_tick == 7


@pytest.mark.parametrize(
    ("reading", "why"),
    [
        ((1, RANGE_M + 8 * SIGMA_M, 0.0, 0.0), None),  # the farthest the noise can reach
        ((1, RANGE_M + 8 * SIGMA_M + 1e-6, 0.0, 0.0), "reading out of bounds"),
        ((1, -1e-9, 0.0, 0.0), "reading out of bounds"),
        ((1, 0.0, 0.0, 0.0), None),
        ((1, 2.0, math.pi, -math.pi), None),
        ((1, 2.0, ANGLE_LIMIT_RAD, -ANGLE_LIMIT_RAD), None),  # the bound itself is in
        ((1, 2.0, -ANGLE_LIMIT_RAD, ANGLE_LIMIT_RAD), None),
        ((1, 2.0, math.pi + 1e-6, 0.0), "reading out of bounds"),
        ((1, 2.0, 0.0, -math.pi - 1e-6), "reading out of bounds"),
        ((1, 1e200, 0.0, 0.0), "reading out of bounds"),
        ((4, 2.0, 0.0, 0.0), "unknown robot"),
    ],
)
def test_a_reading_the_camera_cannot_make_is_refused(reading: tuple, why: str | None) -> None:
    c = checks()
    assert c.observation(obs(1, (reading,))) == why
    assert c.last_tick == (1 if why is None else -1)  # a refused observation moves nothing


@pytest.mark.parametrize(
    ("readings", "why"),
    [
        (((1, 2.0, 0.0, 0.0), (2, 3.0, 0.1, -0.1), (3, 9.0, -3.0, 3.0)), None),
        (((1, 2.0, 0.0, 0.0), (2, 11.0, 0.0, 0.0), (4, 2.0, 0.0, 0.0)), "reading out of bounds"),
        (((1, 2.0, 0.0, 0.0), (4, 2.0, 0.0, 0.0), (2, 11.0, 0.0, 0.0)), "unknown robot"),
        (((1, 2.0, 0.0, 4.0), (2, -1.0, 0.0, 0.0)), "reading out of bounds"),
    ],
)
def test_of_several_readings_the_first_that_fails_names_the_reason(readings: tuple, why: str | None) -> None:
    """A dozen markers in view are checked a column at a time; a refusal still
    gives the reason of the first reading that fails, in the message's order."""
    c = checks()
    assert c.observation(obs(1, readings)) == why


@pytest.mark.parametrize(
    ("obstacle", "why"),
    [
        ((SENSING_M + 1.0, 0.3, 1.0), None),  # its edge at the sensing range
        ((SENSING_M + 1.0 + 1e-6, 0.3, 1.0), "obstacle out of bounds"),
        ((0.5, 0.0, 1.0), None),  # inside it (a collision): still a true reading
        ((-0.1, 0.0, 1.0), "obstacle out of bounds"),
        ((2.0, 0.0, 0.0), "obstacle out of bounds"),
        ((2.0, 0.0, -1.0), "obstacle out of bounds"),
        ((0.0, 0.0, 0.5), None),  # touching it
        ((2.0, ANGLE_LIMIT_RAD, 1.0), None),  # the bound itself is in
        ((2.0, -ANGLE_LIMIT_RAD, 1.0), None),
        ((2.0, math.pi + 1e-6, 1.0), "obstacle out of bounds"),
        ((2.0, -math.pi - 1e-6, 1.0), "obstacle out of bounds"),
    ],
)
def test_an_obstacle_the_leader_cannot_sense_is_refused(obstacle: tuple, why: str | None) -> None:
    assert checks().observation(obs(1, (), (obstacle,))) == why


def test_the_leaders_first_code_is_taken_and_a_coarse_tick_still_allows_two_ahead() -> None:
    c = checks()
    assert c.code(FormationCode(sender=1, seq=1, tick=0, code=1)) is None  # a leader's first message has seq 1
    slow = InboxChecks((1, 2), RANGE_M, SIGMA_M, SENSING_M, dt_s=10.0)  # 5 s is half a tick
    assert slow.code_ahead_ticks == 2  # the leader may be up to two ticks ahead of a follower's clock
    assert (
        slow.code(FormationCode(sender=1, seq=1, tick=1, code=1)) is None
    )  # no observation yet (tick -1): tick 1 is two ahead
    assert slow.code(FormationCode(sender=1, seq=2, tick=2, code=1)) == TICK_AHEAD


def test_codes_must_be_newer_by_tick_then_seq_and_not_far_ahead_of_the_agents_clock() -> None:
    c = checks()
    ahead = math.ceil(5.0 / DT_S)  # CODE_AHEAD_S of ticks
    assert c.code(FormationCode(sender=1, seq=10, tick=3, code=1)) is None
    assert c.code(FormationCode(sender=1, seq=10, tick=3, code=1)) == REPLAYED  # the same code again
    assert c.code(FormationCode(sender=1, seq=9, tick=3, code=1)) == REPLAYED  # the same tick, an older seq
    assert c.code(FormationCode(sender=1, seq=50, tick=2, code=1)) == REPLAYED  # an older tick, whatever its seq
    assert c.code(FormationCode(sender=1, seq=11, tick=3, code=0)) is None  # the same tick, a newer seq
    assert (
        c.code(FormationCode(sender=1, seq=1, tick=4, code=1)) is None
    )  # a restarted leader: seq 1 again, at a later tick
    assert c.observation(obs(20)) is None
    assert c.code(FormationCode(sender=1, seq=2, tick=20 + ahead, code=1)) is None
    assert c.code(FormationCode(sender=1, seq=3, tick=20 + ahead + 1, code=1)) == TICK_AHEAD
    assert c.code(FormationCode(sender=1, seq=4, tick=2**53, code=1)) == TICK_AHEAD
    assert c.last_code == (20 + ahead, 2)  # refused codes move nothing


def test_what_the_link_layer_hands_over_must_be_newer_than_what_it_handed_over_before() -> None:
    """Arrivals and the link layer's output are checked apart: a delayed
    observation taken on arrival long ago still gives its reading when the
    link releases it, while a duplicate or one held behind a newer one does not."""
    c = checks()
    for t in (5, 6, 7):
        assert c.observation(obs(t)) is None  # arrivals: answered
    assert c.reading(obs(5)) is None  # released late by a delay: taken, stale
    assert c.reading(obs(5)) == REPLAYED  # its duplicate
    assert c.reading(obs(7)) is None
    assert c.reading(obs(6)) == REPLAYED  # held behind 7 by a reorder
    assert (c.last_tick, c.last_reading_tick) == (7, 7)
    assert c.code(FormationCode(sender=1, seq=3, tick=0, code=1)) is None
    assert c.code(FormationCode(sender=1, seq=4, tick=0, code=1)) is None
    assert c.handed_code(FormationCode(sender=1, seq=4, tick=0, code=1)) is None
    assert c.handed_code(FormationCode(sender=1, seq=3, tick=0, code=1)) == REPLAYED
    assert c.handed_code(FormationCode(sender=1, seq=4, tick=0, code=1)) == REPLAYED
    assert c.last_handed_code == (0, 4)
