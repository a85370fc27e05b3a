"""Ctrl-C (SIGINT) in the ``swarm`` command, at any moment: one line, exit
code 130, no traceback, no process left.

- While the command's first modules load, SIGINT is held back (blocked):
  handled once they are, never in the middle of an import (numpy's).
- While nothing has started yet (swarm run loading its modules, reading the
  scenario), and once the command has its exit code, a Ctrl-C ends the
  process at once: one line, nothing to stop.
- While the run goes, it is a KeyboardInterrupt: the run stops every process
  and says so in one line (formation_swarm.launch).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

INTERRUPTED = 130  # 128 + SIGINT, as a shell reports it


def hold() -> None:
    """Block SIGINT in this thread (and the threads it starts from now on).
    A process started with SIGINT ignored (a shell's background job, a parent
    that ignores it) takes it as Python's KeyboardInterrupt from here, as it
    does later on: one that comes while held would otherwise be dropped."""
    if threading.current_thread() is threading.main_thread():
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
            signal.signal(signal.SIGINT, signal.default_int_handler)


def release() -> None:
    """Unblock SIGINT: one that came while held is handled now."""
    if threading.current_thread() is threading.main_thread():
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def exit_at_once() -> None:
    """From now on a SIGINT ends the process at once with one line and exit
    code 130: for the moments when nothing is running that needs stopping."""

    def handler(_sig: int, _frame: object) -> None:
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()
            sys.stderr.write("interrupted\n")
            sys.stderr.flush()
        os._exit(INTERRUPTED)

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, handler)
        release()
