"""Stop signals held back while the launcher does what must not be cut short."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def stop_signals_noted(note: Callable[[], None]) -> Iterator[None]:
    """Inside, on the main thread, a SIGINT or SIGTERM that would raise (a
    Python handler) only calls ``note``: what runs inside is not cut short,
    and the signal is not lost either. A SIGINT left to the system's default
    is ignored inside; one the process ignores stays ignored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    for sig, handler in previous.items():
        if callable(handler):
            signal.signal(sig, lambda _sig, _frame: note())
        elif sig == signal.SIGINT and handler == signal.SIG_DFL:
            signal.signal(sig, signal.SIG_IGN)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            if handler is not None:  # None: not set from Python, and left alone here
                signal.signal(sig, handler)
