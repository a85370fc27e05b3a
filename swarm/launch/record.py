"""What a run has said and heard so far: its events and console lines, and
the world's status as it comes."""

from __future__ import annotations

import queue
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
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


def folder_identity(folder: Path) -> tuple[int, int]:
    """The folder's (device, inode): a folder deleted and made again is not the run's."""
    st = folder.stat()
    return (st.st_dev, st.st_ino)


def folder_gone(folder: Path, identity: tuple[int, int] | None) -> str | None:
    """Why the run folder holds none of the run (deleted while it ran, even if
    a process made it again since), or None."""
    try:
        now: tuple[int, int] | None = folder_identity(folder)
    except OSError:
        now = None
    if now is None or (identity is not None and now != identity):
        return f"its folder {folder} was deleted during the run: its recording, logs and stats are lost"
    return None
