"""The launcher's child processes: start one with its log, signal it, reap it,
and explain how it ended (its exit code and the tail of its log)."""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from formation_swarm.runtime import proc as proc_mod
from formation_swarm.runtime import spawner

# One worker thread per Zenoh runtime in each child: five processes share this
# machine's cores, and fewer threads preempt each other less (measured ~+10%
# lockstep ticks/s on 2 cores). A ZENOH_RUNTIME set by the user wins.
CHILD_ZENOH_RUNTIME = (
    "(app: (worker_threads: 1), acc: (worker_threads: 1), tx: (worker_threads: 1), "
    "rx: (worker_threads: 1), net: (worker_threads: 1))"
)
TAIL_LINES = 8  # of a failed child's log, on the console and in its "exited" event
KILLED_AT_STOP_TIMEOUT = "killed after stop timeout"  # the event of a child SIGKILLed at the end of the stop
TAIL_BYTES = 16384  # read from the end of the log for them


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _die_with_parent() -> None:  # pragma: no cover - runs in the child
    """Linux: the child gets SIGTERM if the launcher dies, even by SIGKILL."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


def log_tail(path: Path, lines: int = TAIL_LINES) -> list[str]:
    """The last ``lines`` non-blank lines of a log (none if it cannot be read)."""
    try:
        with open(path, "rb") as f:
            f.seek(max(0, f.seek(0, os.SEEK_END) - TAIL_BYTES))
            text = f.read().decode(errors="replace")
    except OSError:
        return []
    return [line.rstrip() for line in text.splitlines() if line.strip()][-lines:]


def describe_exit(code: int) -> str:
    """``1`` -> "exited with code 1"; ``-9`` -> "was killed by SIGKILL"."""
    if code >= 0:
        return f"exited with code {code}"
    try:
        return f"was killed by {signal.Signals(-code).name}"
    except ValueError:
        return f"was killed by signal {-code}"


@dataclass
class Child:
    name: str
    argv: list[str]
    log_path: Path
    proc: subprocess.Popen[bytes] | spawner.Forked | None = None
    fork: bool = True  # our roles are forked from the spawner (see formation_swarm.runtime.spawner)
    log: Any = None
    stop_sent_at: float | None = None
    exited_at: float | None = None
    reported: bool = False

    @property
    def pid(self) -> int | None:
        return None if self.proc is None else self.proc.pid

    def start(self) -> None:
        self.log = open(self.log_path, "wb")  # noqa: SIM115 - closed in close()
        env = dict(os.environ)
        env.setdefault("ZENOH_RUNTIME", CHILD_ZENOH_RUNTIME)
        module = spawner.forkable(self.argv) if self.fork else None
        # A Ctrl-C in the middle of a start would leave a process running that this
        # object does not know of (the fork server's request half done, or Popen's
        # result lost), which nothing could then stop: it comes once self.proc is set.
        with proc_mod.sigint_deferred():
            if module is not None:
                self.proc = spawner.Forked(module, self.argv, self.log_path, env)
                return
            self.proc = subprocess.Popen(
                self.argv,
                env=env,
                stdout=self.log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
                preexec_fn=_die_with_parent,
            )

    def poll(self) -> int | None:
        if self.proc is None:
            return None
        code = self.proc.poll()
        if code is not None and self.exited_at is None:
            self.exited_at = time.monotonic()
        return code

    def signal(self, sig: int) -> None:
        if self.proc is not None and self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.proc.send_signal(sig)
            if sig in (signal.SIGTERM, signal.SIGINT) and self.stop_sent_at is None:
                self.stop_sent_at = time.monotonic()

    def close(self) -> None:
        if self.log is not None:
            self.log.close()
            self.log = None
