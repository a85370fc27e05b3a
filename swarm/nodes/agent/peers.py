"""What an agent knows of its peers, from their liveliness tokens.

The world: seen (the wait before the run can end), lost mid-run (its token
gone: the world, or only our session to it, may come back, and is waited
for up to a grace time), gone. The logger: present, and left (a follower
stays after the run's end until the logger has its last telemetry). Each
change sets ``changed``, which ends the agent's wait for its peers. No
Zenoh here: the process's liveliness callbacks call in.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable


class Peers:
    def __init__(self, say: Callable[[str], None], world_grace_s: float, world_left: Callable[[], None]) -> None:
        self.say = say
        self.world_grace_s = world_grace_s  # how long a world lost mid-run is waited for
        self._world_left = world_left  # the agent's loop ends
        self.world_seen = False
        self.world_gone = False
        self.world_lost: threading.Timer | None = None  # running while the world's token is away
        self.world_lost_at = 0.0
        self.world_back_after_s: list[float | None] = []  # per loss of the world: how long it was away
        self.changed = threading.Event()  # a matching change, the world's token or a stop
        self.logger_present = False  # the run's logger holds its token
        self.logger_left = threading.Event()  # ... and has undeclared it (or a stop came)

    def world(self, present: bool, *, started: bool, done: bool) -> None:
        """The world's token came (``present``) or went."""
        if present:
            self.world_seen = True
            self.changed.set()
            if self.world_lost is not None:  # back: our session was dropped and regained
                self.world_lost.cancel()
                self.world_lost = None
                self.world_back_after_s[-1] = away = time.monotonic() - self.world_lost_at
                self.say(f"the world is back after {away:.2f} s")
        elif done:
            pass  # the run is over: the world leaves after "done", as it should
        elif self.world_seen and started and self.world_lost is None and not self.world_gone:
            # Mid-run: the world, or only our session to it, may come back.
            self.world_lost_at = time.monotonic()
            self.world_back_after_s.append(None)
            self.say(f"lost the world; waiting up to {self.world_grace_s:g} s for it to come back")
            self.world_lost = threading.Timer(self.world_grace_s, self.leave)
            self.world_lost.daemon = True
            self.world_lost.start()
        elif self.world_seen and not started:
            self.leave()  # before the run: the world gave up

    def leave(self) -> None:
        """The world is gone for good."""
        self.world_gone = True
        self._world_left()

    def logger(self, present: bool) -> None:
        self.logger_present = present
        if not present:
            self.logger_left.set()

    def stop_waiting(self) -> None:
        """No more waiting for a lost world (the agent is leaving)."""
        if self.world_lost is not None:
            self.world_lost.cancel()
