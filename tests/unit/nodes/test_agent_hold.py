"""A frozen robot of a shared process (nodes.agent.hold): what arrives while
it is frozen leaves its channel, in order, up to a bound, and comes first after."""

from __future__ import annotations

import threading
from typing import Any

import pytest
import zenoh

from formation_swarm.nodes.agent import hold as hold_mod
from formation_swarm.nodes.agent.hold import Hold


class Channel:
    """A stand-in FIFO channel: its messages, then None; raises once closed and empty."""

    def __init__(self, messages: list[int]) -> None:
        self.messages = list(messages)
        self.closed = False
        self.taken = 0

    def try_recv(self) -> Any:
        if self.messages:
            self.taken += 1
            return self.messages.pop(0)
        if self.closed:
            raise zenoh.ZError("closed")
        return None


def _thaw_after(h: Hold, channel: Channel, taken: int) -> threading.Thread:
    """A thread that thaws ``h`` once ``taken`` messages have left ``channel``."""

    def thaw() -> None:
        while channel.taken < taken:
            threading.Event().wait(0.001)
        h.running.set()

    t = threading.Thread(target=thaw)
    t.start()
    return t


def test_a_frozen_robots_messages_leave_its_channel_in_order_and_come_first(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hold_mod, "DRAIN_PERIOD_S", 0.001)
    h, channel = Hold(), Channel(list(range(10)))
    h.running.clear()
    t = _thaw_after(h, channel, 10)
    h.wait(channel)
    t.join(timeout=10)
    assert (list(h.held), channel.messages) == (list(range(10)), [])
    channel.messages = [10, 11]  # arrived after the thaw: after what was held
    assert [h.next(channel) for _ in range(13)] == [*range(12), None]


def test_what_is_held_is_bounded_the_rest_waits_in_the_channel(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hold_mod, "DRAIN_PERIOD_S", 0.001)
    monkeypatch.setattr(hold_mod, "MAX_HELD", 4)
    h, channel = Hold(), Channel(list(range(10)))
    h.running.clear()
    t = _thaw_after(h, channel, 4)
    h.wait(channel)
    t.join(timeout=10)
    assert (len(h.held), len(channel.messages)) == (4, 6)
    channel.closed = True  # closed: the held and queued are still read, then the close is raised
    assert [h.next(channel) for _ in range(10)] == list(range(10))
    with pytest.raises(zenoh.ZError):
        h.next(channel)


def test_a_kill_or_stop_while_frozen_ends_the_wait_on_a_closed_channel() -> None:
    h, channel = Hold(), Channel([1])
    channel.closed = True
    h.running.clear()
    done = threading.Event()
    t = threading.Thread(target=lambda: (h.wait(channel), done.set()))
    t.start()
    assert done.wait(timeout=5)  # returns within a drain period once the channel is closed
    t.join(timeout=5)
    assert list(h.held) == [1]
