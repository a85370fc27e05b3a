"""What a run has said and heard so far: its events and console lines, and
the world's status as it comes."""

from __future__ import annotations

import queue
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.messages import Status


@dataclass
class Journal:
    """The run's events (for the summary) and its console."""

    say: Callable[[str], None]
    events: list[dict[str, Any]] = field(default_factory=list)
    started_at: float = 0.0  # monotonic: when the first process started

    def add(self, event: str, **fields: Any) -> None:
        self.events.append({"event": event, **fields})

    def wall_s(self) -> float:
        """Wall time since the run's first process started, in s."""
        return time.monotonic() - self.started_at


class StatusFeed:
    """The world's Status messages, put by a Zenoh callback and read by the launcher's loop."""

    def __init__(self) -> None:
        self.queue: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        self.first: Status | None = None  # the world's first status: the run's start
        self.last: Status | None = None

    def put(self, payload: bytes) -> None:  # a Zenoh thread: hands over only
        self.queue.put(payload)

    def read(self) -> None:
        """Take what has come: the first and the newest status by sequence number."""
        rej = Rejections()
        while True:
            try:
                payload = self.queue.get_nowait()
            except queue.Empty:
                return
            st = rej.decode(Status, payload)
            if st is not None and (self.first is None or st.seq < self.first.seq):
                self.first = st
            if st is not None and (self.last is None or st.seq > self.last.seq):
                self.last = st

    def sim_time(self) -> float:
        """The newest status's sim time in s, -1 before the first."""
        self.read()
        return -1.0 if self.last is None else self.last.time_s

    @property
    def done(self) -> bool:
        return self.last is not None and self.last.state == "done"
