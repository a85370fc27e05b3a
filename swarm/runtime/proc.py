"""Process plumbing shared by every role: stop signals, atomic JSON files."""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

# CPython runs a signal handler on the main thread, between two bytecodes. A
# signal that comes after the thread's last look and before it blocks on a
# lock (threading.Event.wait) is handled only when that wait ends, so the main
# thread never waits on an Event longer than this at a time (wait_for): that
# rare race costs at most this much, and a set event still ends the wait at
# once. (A Zenoh channel's recv looks for signals itself.)
SIGNAL_CHECK_S = 0.1
# At exit, how long a role waits for what it wrote to reach its peers (wait_sent).
SEND_DRAIN_S = 5.0


class StopEvent(threading.Event):
    """An event that also calls its wakers when set, for a loop blocked in a
    call no timeout ends (a Zenoh channel's ``recv``): the waker ends it."""

    def __init__(self) -> None:
        super().__init__()
        self._wakers: list[Callable[[], None]] = []
        self.signum: int | None = None  # the signal that set it, if one did

    @property
    def exit_code(self) -> int:
        """128 + the signal's number (130 SIGINT, 143 SIGTERM), as a shell reports it."""
        return 128 + (self.signum or signal.SIGINT)

    def add_waker(self, waker: Callable[[], None]) -> None:
        self._wakers.append(waker)
        if self.is_set():
            waker()

    def set(self) -> None:
        super().set()
        for waker in list(self._wakers):
            waker()


def install_stop_handlers() -> StopEvent:
    """SIGINT and SIGTERM set an event that every loop checks.

    The handler sets it from a thread of its own: the handler runs on the
    main thread, possibly while that thread holds the lock of one of the very
    events the wakers set (inside its ``wait``), and those locks are not
    reentrant."""
    stop = StopEvent()

    def handler(sig: int, _frame: object) -> None:
        if stop.signum is None:
            stop.signum = sig
        with contextlib.suppress(RuntimeError):  # no new thread at interpreter exit: it is exiting anyway
            threading.Thread(target=stop.set, name="stop-signal", daemon=True).start()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return stop


def exit_after_main(code: int) -> None:
    """Exit with ``code`` once a role's main() has returned. A SIGINT or SIGTERM
    that comes now (a launcher stopping every process as the run ends) finds
    the work done: it is ignored. Otherwise the interpreter's shutdown puts
    the default action back and such a signal would kill the process (-15)
    after it had finished cleanly."""
    ignore_stop_signals()
    sys.exit(code)


def ignore_stop_signals() -> None:
    """SIGINT and SIGTERM ignored from now on: for a process whose work is done."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)


def unsent_bytes() -> int:
    """Bytes this process has written to its TCP sockets that the peers' kernels
    have not acknowledged yet (Linux ``SIOCOUTQ``); 0 where /proc is missing."""
    import fcntl
    import socket
    import struct
    import termios

    total = 0
    try:
        fds = os.listdir("/proc/self/fd")
    except OSError:
        return 0
    for name in fds:
        fd = int(name)
        try:
            if not os.readlink(f"/proc/self/fd/{name}").startswith("socket:"):
                continue
            sock = socket.socket(fileno=fd)
            try:
                tcp = sock.family in (socket.AF_INET, socket.AF_INET6) and sock.type == socket.SOCK_STREAM
            finally:
                sock.detach()  # the fd stays ours, open
            if not tcp:
                continue
            total += struct.unpack("i", fcntl.ioctl(fd, termios.TIOCOUTQ, b"\0" * 4))[0]  # TIOCOUTQ == SIOCOUTQ
        except OSError:
            continue  # closed meanwhile, or not a socket we can ask
    return total


def wait_sent(timeout_s: float, poll_s: float = 0.01) -> int:
    """Wait until every byte this process wrote to its TCP sockets has reached
    the peer's kernel, at most ``timeout_s``; the bytes still unsent then.

    A process that exits while its socket still holds unread input makes Linux
    send a reset instead of closing, and the reset throws away what was written
    but not yet acknowledged: a lockstep agent's last telemetry batches, stuck
    behind a slow logger, were lost that way (data the peer's kernel already
    acknowledged survives a reset). So a role waits for this before it exits.
    Zenoh writes on its own threads; a Zenoh put has returned once the bytes are
    in our kernel's send buffer, not once they have left it."""
    deadline = time.monotonic() + timeout_s
    while (left := unsent_bytes()) > 0 and time.monotonic() < deadline:
        time.sleep(poll_s)
    return left


def wait_for(event: threading.Event, timeout_s: float | None = None) -> bool:
    """``event.wait(timeout_s)`` for the main thread: in slices of at most
    SIGNAL_CHECK_S, so that a stop signal is never left unhandled longer."""
    end = math.inf if timeout_s is None else time.monotonic() + timeout_s
    while not event.is_set():
        left = end - time.monotonic()
        if left <= 0:
            return False
        event.wait(min(left, SIGNAL_CHECK_S))
    return True


class OutlivesItsReader:
    """A text stream whose writes go nowhere once its reader has left, instead
    of raising BrokenPipeError into the program (``swarm run ... | head -1``:
    the run goes on to its end and writes its folder). Everything else is the
    wrapped stream's."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream
        self.reader_gone = False

    def write(self, text: str) -> int:
        if not self.reader_gone:
            try:
                return self._stream.write(text)
            except BrokenPipeError:
                self._leave()
        return len(text)

    def flush(self) -> None:
        if not self.reader_gone:
            try:
                self._stream.flush()
            except BrokenPipeError:
                self._leave()

    def _leave(self) -> None:
        """Point the stream's descriptor at /dev/null, so that what its buffer
        still holds is flushed there at exit rather than raising again."""
        self.reader_gone = True
        with contextlib.suppress(OSError, ValueError, AttributeError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())
            os.close(devnull)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def interrupt_on_stop_signals() -> None:
    """SIGINT and SIGTERM raise KeyboardInterrupt in the main thread, even when the
    process was started with SIGINT ignored (as a shell's background jobs are):
    for the commands that stop their children cleanly in an ``except``."""

    def handler(_sig: int, _frame: object) -> None:
        raise KeyboardInterrupt

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, handler)


def realtime_priority(priority: int) -> str:
    """Put the calling thread, and every thread it starts from now on, in
    Linux's round-robin real-time class at ``priority`` (1-99; 0 leaves the
    normal class), and say what it got. A process without the right to
    (CAP_SYS_NICE, or an RLIMIT_RTPRIO of at least ``priority``) stays in the
    normal class: the reason is in the answer, nothing is raised.

    For the real-time world: a runnable real-time thread runs before every
    normal one, so its ticks start on time however busy the cores are with
    agents. By default the kernel keeps 5% of each second for the normal
    class (sched_rt_runtime_us), so even a real-time thread that never
    blocked could not take a core for good."""
    if not 0 <= priority <= 99:
        raise ValueError(f"a real-time priority is in [0, 99], got {priority}")
    if priority == 0:
        return "normal"
    policy = getattr(os, "SCHED_RR", None)
    if policy is None or not hasattr(os, "sched_setscheduler"):
        return "normal (no real-time class on this system)"
    try:
        os.sched_setscheduler(0, policy, os.sched_param(priority))
    except OSError as exc:
        return (
            f"normal (real-time priority {priority} refused: {exc.strerror or exc}; it needs root or CAP_SYS_NICE, "
            f"or an RLIMIT_RTPRIO of at least {priority}, e.g. ulimit -r {priority}, and real-time CPU time "
            "in its cgroup)"
        )
    return f"real-time (SCHED_RR {priority})"


def write_json(path: str | None, data: dict[str, Any]) -> None:
    """Write ``data`` atomically (a crash leaves the old file or none, never
    half); a write that fails (a full disk) raises OSError and leaves no
    temporary file behind."""
    if not path:
        return
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(p.suffix + ".tmp")
    text = json.dumps(clean_json(data), indent=2, allow_nan=False)
    try:
        tmp.write_text(text)
        tmp.replace(p)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise


class JsonWriter:
    """Writes the newest of the snapshots it is offered to ``path`` (atomically,
    as :func:`write_json`) from a thread of its own, so that a slow disk never
    holds up the caller's loop: with 100 agents each replacing its counters
    file, opening and renaming one took 11-46 ms (strace), up to a tick of a
    20 Hz run. A snapshot offered while one is being written replaces any
    still waiting. :meth:`close` hands over the last one, which the thread
    writes after every other (the caller never writes the file itself, so two
    writers never share its temporary file), and waits at most ``timeout_s``
    for it."""

    def __init__(self, path: str | None, name: str = "json-writer") -> None:
        self.path = path
        self._pending: dict[str, Any] | None = None
        self._cond = threading.Condition()
        self._closed = False
        self.errors = 0
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        if path:
            self._thread.start()

    def offer(self, data: dict[str, Any]) -> dict[str, Any] | None:
        """Hand over ``data``, copied here (its lists and dicts, which the
        caller may go on changing while the thread writes); the copy (None:
        no path, nothing written)."""
        if not self.path:
            return None
        snapshot: dict[str, Any] = clean_json(data)
        with self._cond:
            self._pending = snapshot
            self._cond.notify()
        return snapshot

    def close(self, last: dict[str, Any] | None = None, timeout_s: float = 5.0) -> None:
        snapshot = None if last is None or not self.path else clean_json(last)
        with self._cond:
            if snapshot is not None:
                self._pending = snapshot
            self._closed = True
            self._cond.notify()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._closed:
                    self._cond.wait()
                data, self._pending = self._pending, None
                closed = self._closed
            if data is not None:
                try:
                    write_json(self.path, data)
                except (OSError, ValueError):
                    self.errors += 1  # the next snapshot, or the last one close() hands over, tries again
            if closed:
                return


def clean_json(o: Any) -> Any:
    """NaN and inf become None (JSON has neither); tuples become lists."""
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {str(k): clean_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [clean_json(v) for v in o]
    return o


@contextlib.contextmanager
def sigint_deferred() -> Iterator[None]:
    """SIGINT and SIGTERM noted inside (on the main thread) and raised as
    KeyboardInterrupt when it ends: a Ctrl-C then interrupts what comes after,
    not an exchange half done. (Masking the signal would not do: the kernel
    hands it to any thread that does not mask it, Zenoh's among them, and
    Python runs the handler in the main thread wherever it stands.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    stops = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, lambda sig, _frame: came.append(sig)) for sig in stops}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if came and any(callable(previous[sig]) or previous[sig] == signal.SIG_DFL for sig in came):
        raise KeyboardInterrupt
