"""A fault schedule's times against what a run can count: a start past the
run's end, a length of more ticks than a message carries, a number too large
for a float: each a ValueError naming the fault, never an OverflowError."""

from __future__ import annotations

import pytest

from formation_swarm.common import checks
from formation_swarm.common.faults import Fault
from formation_swarm.common.faults.schedule import check_against
from formation_swarm.protocol import codec

LIMIT = "must be at most 2**53 ticks of run.dt_s = 0.05 s (about 4.504e+14 s, the most a message's tick count carries)"


def test_the_most_ticks_a_run_counts_is_what_a_message_carries() -> None:
    # common sits below protocol and repeats the number: the two stay equal.
    assert checks.MAX_TICKS == codec.MAX_TICK == 2**53
    assert checks.tick_limit(0.05) == LIMIT.removeprefix("must be at most ")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("kill agent-3@1e308s", "fault 'kill agent-3@1e+308s': starts at 1e+308 s, at or after the run's end (56 s;"),
        ("drop obs:2@1s for=1e308s p=0.5", f"fault 'drop obs:2@1s for=1e+308s p=0.5': for {LIMIT}, got 1e+308 s"),
        ("freeze agent-2@1s for=1e300s", f"for {LIMIT}, got 1e+300 s"),
        ("restart agent-2@1s after=1e308s", f"fault 'restart agent-2@1s after=1e+308': after {LIMIT}, got 1e+308 s"),
    ],
)
def test_a_time_the_run_cannot_count_is_refused_naming_the_fault(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=r"^fault '") as info:
        check_against([Fault.parse(text)], robots=(1, 2, 3), leader_id=1, duration_s=56.0, dt_s=0.05)
    assert message in str(info.value)


def test_an_integer_too_large_for_a_float_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="fault 'kill': the start must be a time >= 0 s, got 1000"):
        Fault.make("kill", "agent-2", 10**400)
    with pytest.raises(ValueError, match="fault 'freeze': for must be a time >= 0 s, got 1000"):
        Fault.make("freeze", "agent-2", 1, for_s=10**400)
    with pytest.raises(ValueError, match="fault 'bias': rho_m must be a finite number, got 1000"):
        Fault.make("bias", "2", 1, rho_m=10**400)
