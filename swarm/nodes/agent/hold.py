"""One robot of a shared process held (nodes.agent.shared): frozen or killed.

A freeze holds the robot's loop as SIGSTOP holds a process of its own: what
arrives for it waits, and after the thaw it takes all of it in order and
answers the newest observation. Its inbox (a Zenoh FIFO channel of
node.INBOX_CAPACITY) cannot hold a long freeze: in real time it fills in
about 12 s, and a full channel blocks Zenoh's receiving thread, which the
process's robots share, so its neighbours stopped hearing the world too
(11 robots, K = 10, agent-5 frozen 22 s: its nine neighbours answered 396
of 600 ticks). So while frozen the loop moves what has arrived, untouched,
into a list of its own every DRAIN_PERIOD_S, up to MAX_HELD messages; past
that the channel fills and blocks as before, so a flood on a frozen robot
holds at most MAX_HELD + the channel's messages (of at most 40 KiB each).
"""

from __future__ import annotations

import collections
import threading
from typing import Any

import zenoh

DRAIN_PERIOD_S = 0.25  # a channel of 256 takes at least 3 s to fill at 20 ticks/s
MAX_HELD = 2048  # messages: at least 50 s of a frozen follower's inbox; 80 MiB of a flood's


class Hold:
    """Frozen (``running`` cleared) or killed; what arrived while frozen, in order."""

    def __init__(self) -> None:
        self.running = threading.Event()
        self.running.set()
        self.killed = False
        self.held: collections.deque[Any] = collections.deque()

    def wait(self, channel: Any) -> None:
        """Until thawed (or killed, or stopped: they set ``running``), moving
        what arrives on ``channel`` into ``held``, up to MAX_HELD."""
        while not self.running.wait(DRAIN_PERIOD_S):
            while len(self.held) < MAX_HELD:
                try:
                    sample = channel.try_recv()
                except zenoh.ZError:
                    return  # closed: the loop takes what is held, then ends
                if sample is None:
                    break
                self.held.append(sample)

    def next(self, channel: Any) -> Any:
        """The next message that has arrived, held ones first; None if none (raises once the channel is closed)."""
        return self.held.popleft() if self.held else channel.try_recv()
