"""The world's alarm: what wakes its command loop at a deadline."""

from __future__ import annotations

import queue
import time

import pytest

from formation_swarm.nodes.world.inbox import Alarm


def test_alarm_fires_once_at_its_latest_time_and_earlier_when_moved_earlier() -> None:
    fired: queue.SimpleQueue[float] = queue.SimpleQueue()
    alarm = Alarm(lambda: fired.put(time.monotonic()))
    try:
        t0 = time.monotonic()
        alarm.set(t0 + 0.2)
        alarm.set(t0 + 0.4)  # later: not at 0.2
        at = fired.get(timeout=5)
        assert at >= t0 + 0.4
        t1 = time.monotonic()
        alarm.set(t1 + 30.0)
        alarm.set(t1 + 0.1)  # earlier: at 0.1, not 30
        at = fired.get(timeout=5)
        assert t1 + 0.1 <= at < t1 + 5
        assert fired.empty()  # once per set
    finally:
        alarm.close()


def test_closed_alarm_never_fires() -> None:
    fired: queue.SimpleQueue[float] = queue.SimpleQueue()
    alarm = Alarm(lambda: fired.put(time.monotonic()))
    alarm.set(time.monotonic() + 0.1)
    alarm.close()
    assert not alarm._thread.is_alive()
    with pytest.raises(queue.Empty):
        fired.get(timeout=0.3)  # past its time: it would have fired by now
