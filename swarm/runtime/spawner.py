"""Fast start for many roles on one machine: import once, fork per process.

A role started as ``python -m formation_swarm.nodes.agent.main ...`` spends about
0.9 s of CPU importing some 900 modules (filterpy pulls in scipy.stats) before
it does anything, and each process then holds its own copy of them. Here the
launcher's roles are forked instead from one server process that imported them
once (``multiprocessing``'s forkserver, with :mod:`formation_swarm.nodes.preload`
as its preload). The server holds no Zenoh session and runs no thread when it
forks (numpy's BLAS is kept to the calling thread there), so each child starts
with a clean runtime and opens its own session.

A forked child is the same process a ``python -m`` one would be: its own
session (setsid), stdin from /dev/null, stdout and stderr into its log, the
launcher's current environment, ``sys.argv`` as ``-m`` sets it, the command line
``ps`` shows (setproctitle), SIGTERM when its parent dies (the server dies with
the launcher), and the exit codes ``subprocess`` reports (``-9`` for SIGKILL).
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import importlib
import multiprocessing
import multiprocessing.forkserver
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator, Mapping, Sequence
from multiprocessing import resource_tracker
from pathlib import Path
from typing import Any

from formation_swarm.runtime import proc

# The roles the server imports ahead (the logger's rerun starts threads on
# import, so the logger is forked too but imports rerun itself, after the fork).
PRELOAD = "formation_swarm.nodes.preload"
UNREPORTED = 255  # multiprocessing's exit code when the fork server did not report one
FORKED_ROLES = (
    "formation_swarm.nodes.agent.main",
    "formation_swarm.nodes.agent.shared",
    "formation_swarm.nodes.world.main",
    "formation_swarm.nodes.logger.main",
)
_LOCK = threading.Lock()
_context: Any = None


def forkable(argv: Sequence[str]) -> str | None:
    """The role module of ``[sys.executable, "-m", MODULE, ...]`` when it is one
    of ours, else None (another interpreter or program: started with exec)."""
    if len(argv) >= 3 and argv[0] == sys.executable and argv[1] == "-m" and argv[2] in FORKED_ROLES:
        return argv[2]
    return None


def _forkserver() -> Any:
    global _context  # noqa: PLW0603 - one server per launcher process, started on first use
    with _LOCK:
        if _context is None:
            ctx = multiprocessing.get_context("forkserver")
            ctx.set_forkserver_preload([PRELOAD])
            _leave_main_alone()
            # Before either starts: a Ctrl-C as they start must not leave them unstopped.
            atexit.unregister(_stop_server)
            atexit.register(_stop_server)
            # Started with SIGINT blocked, which the exec'd server inherits: a Ctrl-C
            # meant for the launcher would otherwise end its imports with a traceback
            # (the server ignores it itself once they are done, which drops one held
            # back meanwhile). Blocked here, not ignored: ignoring it would drop a
            # Ctrl-C meant for the launcher too; this one is raised once the server
            # runs. The resource tracker starts first: starting it unblocks SIGINT.
            # The roles lift the block (_child).
            resource_tracker.ensure_running()
            with proc.sigint_deferred(), _sigint_blocked():
                multiprocessing.forkserver.ensure_running()
            _context = ctx
        return _context


@contextlib.contextmanager
def _sigint_blocked() -> Iterator[None]:
    """SIGINT blocked in this thread inside: a program started here inherits the
    block, and one that comes for this thread is held back until the end."""
    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


STOP_WAIT_S = 2.0  # the longest the launcher's exit waits for its fork server, and for its resource tracker
SERVER_GRACE_S = 0.5  # after its pipe closed: a server in its loop leaves at once, one still importing never


def _stop_server() -> None:
    """At the launcher's exit: end the fork server and the resource tracker and
    wait for them, so that none outlives the command that started it (nor
    holds its stdout open). A server still importing the roles' modules
    (10-20 s on a loaded machine) reads the pipe that tells it to leave only
    once done, so it is sent SIGTERM after SERVER_GRACE_S; until it is gone,
    a start request it never read keeps the tracker's pipe open. Uses
    multiprocessing's private fields (Python 3.11-3.13); without them, both
    end alone once the server is done."""
    import multiprocessing.forkserver as fs

    server = getattr(fs, "_forkserver", None)
    pid, alive = getattr(server, "_forkserver_pid", None), getattr(server, "_forkserver_alive_fd", None)
    if isinstance(pid, int) and isinstance(alive, int):
        with contextlib.suppress(OSError):
            os.close(alive)  # what the server waits on: closed, it exits
        server._forkserver_alive_fd = None
        if not _reaped(pid, SERVER_GRACE_S):
            for sig in (signal.SIGTERM, signal.SIGKILL):
                with contextlib.suppress(OSError):
                    os.kill(pid, sig)
                if _reaped(pid, STOP_WAIT_S):
                    break
        server._forkserver_pid = None
    _stop_tracker()


def _stop_tracker() -> None:
    """Close this process's end of the resource tracker's pipe and wait for the
    tracker to leave (it does once every end is closed). It ignores SIGINT and
    SIGTERM by design, to unlink what its processes leaked: it is not killed."""
    tracker = getattr(resource_tracker, "_resource_tracker", None)
    fd, pid = getattr(tracker, "_fd", None), getattr(tracker, "_pid", None)
    if not isinstance(fd, int) or not isinstance(pid, int):
        return
    with contextlib.suppress(OSError):
        os.close(fd)
    tracker._fd = None  # type: ignore[union-attr]
    if _reaped(pid, STOP_WAIT_S):
        tracker._pid = None  # type: ignore[union-attr]


def _reaped(pid: int, wait_s: float) -> bool:
    """Whether child ``pid`` ended (and was reaped) within ``wait_s``; True for one not ours."""
    import time

    deadline = time.monotonic() + wait_s
    while True:
        try:
            if os.waitpid(pid, os.WNOHANG)[0] == pid:
                return True
        except ChildProcessError:
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.005)


def _leave_main_alone() -> None:
    """A forked role does not run the launcher's main script again.

    multiprocessing has each child run its parent's ``__main__`` again (as
    ``__mp_main__``), so that functions defined there can be unpickled: a
    ``swarm`` command's children imported the CLI, a benchmark's the launcher
    (about 20 ms of CPU each, 2 s for 100 agents on a machine that has two
    cores for them). A role's target is :func:`_child` of this module, and it
    needs nothing of that script."""
    import multiprocessing.spawn as spawn

    if getattr(spawn.get_preparation_data, "_leaves_main_alone", False):
        return
    prepare = spawn.get_preparation_data

    def get_preparation_data(name: str) -> dict[str, Any]:
        data = prepare(name)
        if name in FORKED_ROLES:  # our Forked processes, named after their role's module
            data.pop("init_main_from_path", None)
            data.pop("init_main_from_name", None)
        return data

    get_preparation_data._leaves_main_alone = True  # type: ignore[attr-defined]
    spawn.get_preparation_data = get_preparation_data


def warm() -> None:
    """Start the fork server now, so that the first role forked later does not
    wait for it (a ``swarm host`` does this before it announces itself)."""
    import multiprocessing.forkserver

    _forkserver()
    multiprocessing.forkserver.ensure_running()


class Forked:
    """A forked role, with the part of ``subprocess.Popen`` the launcher uses."""

    def __init__(self, module: str, argv: Sequence[str], log_path: Path, env: Mapping[str, str]) -> None:
        self.args = list(argv)
        self.exit_path = f"{log_path}.exit"  # the child's own record of its exit code, removed once read
        self._p = _forkserver().Process(
            target=_child,
            args=(module, list(argv), str(log_path), dict(env), self.exit_path),
            name=module,
            daemon=True,
        )
        self._p.start()  # not to be interrupted: Child.start holds a Ctrl-C back until it returns
        self.pid: int = self._p.pid
        self.returncode: int | None = None
        self.unreported = False  # the fork server did not report the exit code: taken from the child's record

    def poll(self) -> int | None:
        if self.returncode is None:
            code = self._p.exitcode
            if code == UNREPORTED:
                # multiprocessing's stand-in when it could not read the code from
                # the fork server (seen once in the test suites, for a world whose
                # log said exit code 0); our roles never exit 255 themselves, and
                # each writes its code before it exits.
                with contextlib.suppress(OSError, ValueError):
                    code = int(Path(self.exit_path).read_text())
                    self.unreported = True
            self.returncode = code
            if code is not None:
                with contextlib.suppress(OSError):
                    os.unlink(self.exit_path)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        self._p.join(timeout)
        code = self.poll()
        if code is None:
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
        return code

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, sig)


def _child(  # pragma: no cover - child
    module: str, argv: list[str], log_path: str, env: dict[str, str], exit_path: str
) -> None:
    """What runs in the forked process: become the ``python -m`` role, run its
    main, then exit as :func:`formation_swarm.runtime.proc.exit_after_main` does."""
    # What exec would have closed: the server's sockets and pipes, among them the
    # write end of the pipe by which the server sees the launcher die (held here,
    # it would keep the server, and so this process, alive after the launcher).
    os.closerange(3, os.sysconf("SC_OPEN_MAX"))
    os.setsid()
    # The log first: whatever ends this process from here says why there.
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    # The server started with SIGINT blocked (_forkserver): ignored, as it was, until the
    # role sets its own handlers.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    if os.getppid() == 1:  # the server died before the prctl: so did the launcher
        print(f"{module.split('.')[-2]}: its launcher died as it started: not starting", file=sys.stderr, flush=True)
        os._exit(128 + signal.SIGTERM)
    with contextlib.suppress(ImportError):  # first: it takes its room from the environment's memory
        import setproctitle

        setproctitle.setproctitle(" ".join(argv))
    os.environ.clear()
    os.environ.update(env)
    mod = importlib.import_module(module)
    sys.argv = [str(mod.__file__), *argv[3:]]
    code: Any = 1
    try:
        code = mod.main(argv[3:])
    except SystemExit as exc:
        code = exc.code
    except BaseException:  # noqa: BLE001 - reported as an uncaught exception would be
        import traceback

        traceback.print_exc()
        code = 1
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # done: a stop signal now finds nothing to stop
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        atexit._run_exitfuncs()
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
    if code is None:
        code = 0
    elif not isinstance(code, int):
        print(code, file=sys.stderr, flush=True)
        code = 1
    code &= 0xFF
    with contextlib.suppress(OSError):
        Path(exit_path).write_text(str(code))  # read only if the fork server does not report it (Forked.poll)
    os._exit(code)
