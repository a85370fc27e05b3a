"""What reaches the world's loop: the agents' commands, liveliness changes,
wake-ups.

Commands come through a Zenoh FIFO channel read on the loop's own thread
(one thread switch per message; a callback thread and a queue made two).
That recv has no timeout: a deadline (:class:`Alarm`), a tick of the wall
clock, a liveliness change or a stop signal wakes it with a local put on
``Keys.world_wake``, which only the world subscribes to.
"""

from __future__ import annotations

import collections
import contextlib
import math
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from formation_swarm.protocol.keys import Keys
from formation_swarm.runtime.spool import SpoolWriter

# Lockstep holds at most one command per robot here; when full, Zenoh waits
# for the loop (back-pressure) rather than dropping.
CMD_CAPACITY = 1024


class Alarm:
    """Calls ``wake`` at a time of ``time.monotonic()``, from a thread of its own.

    Moving the alarm later costs no thread switch: the thread wakes at the
    earlier time, sees the later one and sleeps again. So a lockstep world can
    re-arm its deadline every tick and the thread wakes once per deadline
    span, not once per tick.
    """

    def __init__(self, wake: Callable[[], None]) -> None:
        self._wake = wake
        self._at = math.inf
        self._closed = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="world-alarm", daemon=True)
        self._thread.start()

    def set(self, at: float) -> None:
        with self._cond:
            if at < self._at:
                self._cond.notify()
            self._at = at

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify()
        self._thread.join(timeout=1.0)

    def _run(self) -> None:
        while True:
            with self._cond:
                while (left := self._at - time.monotonic()) > 0 and not self._closed:
                    self._cond.wait(None if left == math.inf else left)
                if self._closed:
                    return
                self._at = math.inf
            self._wake()


class Inbox:
    """The loop's one place to wait: it hands each command payload, with the
    robot its key names (None: no robot), to ``on_command`` and each
    liveliness change to ``on_alive``, on the loop's thread."""

    def __init__(
        self,
        sess: zenoh.Session,
        keys: Keys,
        robots: tuple[int, ...],
        on_command: Callable[[int | None, bytes], None],
        on_alive: Callable[[str, bool], None],
        *,
        spool: SpoolWriter | None = None,
    ) -> None:
        self.keys = keys
        self.spool = spool  # each command as taken, for the wire recording, at the world's tick (None: not kept)
        self.engine: Any = None  # the world's engine, for its tick (set with a spool)
        self.on_command = on_command
        self.on_alive = on_alive
        self.wakes = 0  # deadlines, clock ticks, liveliness, stop: not commands
        self.events: collections.deque[tuple[str, bool]] = collections.deque()  # liveliness, from its callback
        self.cmd_ids = {keys.cmd(rid): rid for rid in robots}  # each robot's command key, parsed once
        block = zenoh.CongestionControl.BLOCK
        # Its own wake-ups stay in its session: no other process hears them, logins or not.
        self.wake_pub = sess.declare_publisher(
            keys.world_wake, congestion_control=block, allowed_destination=zenoh.Locality.SESSION_LOCAL
        )
        self.cmds = sess.declare_subscriber(keys.all_cmd, zenoh.handlers.FifoChannel(CMD_CAPACITY))
        self.alarm = Alarm(self.wake)

    # -- Zenoh callbacks: short, hand the event to the loop and wake it ----------
    def alive_changed(self, sample: zenoh.Sample) -> None:
        self.events.append((str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))
        self.wake()

    def wake(self) -> None:
        with contextlib.suppress(zenoh.ZError):  # a stop signal may come after the session closed
            self.wake_pub.put(b"")

    def notify(self, key: str) -> None:
        """An event of the world's own (not a token) for ``on_alive``, as a token's going."""
        self.events.append((key, False))
        self.wake()

    # -- the loop's side -----------------------------------------------------------
    def drain(self, until: float) -> None:
        """Handle what has arrived; if nothing has, wait for it until ``until``
        (``time.monotonic()``), or until a wake-up (liveliness, stop)."""
        channel = self.cmds.handler
        sample = channel.try_recv()
        if sample is None and not self.events and until > time.monotonic():
            self.alarm.set(until)
            sample = channel.recv()
        while sample is not None:
            self._on_sample(sample)
            sample = channel.try_recv()
        while self.events:
            self.on_alive(*self.events.popleft())

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        rid = self.cmd_ids.get(key)
        if rid is None:
            if key == self.keys.world_wake:
                self.wakes += 1
                return
            rk = self.keys.parse_robot(key)
            rid = None if rk is None else rk.robot_id
        payload = sample.payload.to_bytes()
        if self.spool is not None:
            self.spool.add(key, payload, None if self.engine is None else self.engine.tick)
        self.on_command(rid, payload)

    def close(self) -> None:
        self.alarm.close()
