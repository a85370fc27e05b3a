"""Two runs' link counts compared."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def assert_same_links(a: dict[str, Any], b: dict[str, Any], partial: Sequence[str] = ()) -> None:
    """Two runs' link counts: the same, but for the leader's very last formation
    code, which may reach a follower after the world's "done" has closed its
    inbox (the run is over; no trajectory depends on it): one code either way;
    and but for the ``partial`` links, received by an agent that was SIGKILLed,
    whose counts are those of its last write (every second of wall time)."""
    assert a.keys() - set(partial) == b.keys() - set(partial)  # one killed before its first write has none
    for name in a.keys() - set(partial):
        if name.startswith("formation:"):
            assert abs(a[name]["received"] - b[name]["received"]) <= 1, name
            assert (a[name]["dropped"], a[name]["partitioned"]) == (b[name]["dropped"], b[name]["partitioned"])
        else:
            assert a[name] == b[name], name
