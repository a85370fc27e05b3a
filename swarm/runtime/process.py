"""What the world, agent, logger and router processes share: exit codes, the
peers deadline (``--peers-timeout``), their one-line reports, and a Zenoh
session opened so that a stop signal or the deadline ends the wait.

``zenoh.open`` blocks while a client retries an absent router (up to
``connect/timeout_ms``, which protocol.session sets), and Python runs signal
handlers only on the main thread between bytecodes: a SIGTERM would wait for
the open to end. So the open runs on a thread of its own and the main thread
waits for it, for a stop signal or for the deadline, whichever comes first.
An open given up that way is left to the process's exit (a session that is
still connecting has no callback thread to hang it).

One deadline per process, set when ``main()`` starts, covers the connection
to the router and the wait for the peers: a role whose router or peers do
not come within ``--peers-timeout`` seconds says what is missing and exits
with ``EXIT_NO_PEERS``.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
import warnings
from typing import TYPE_CHECKING

from formation_swarm.runtime.proc import StopEvent, install_stop_handlers, wait_for

if TYPE_CHECKING:
    import zenoh

    from formation_swarm.spec.scenario import Scenario

EXIT_OK = 0
EXIT_FAILED = 1  # the Zenoh session (or the logger's recording) could not be opened
EXIT_USAGE = 2  # bad flags or scenario (argparse's own code for bad flags)
EXIT_NO_PEERS = 3  # the router or the peers did not appear within --peers-timeout
EXIT_DUPLICATE = 4  # an agent for this robot, or a world, is already in the run
EXIT_HUNG = 5  # (agent) its controller's call had not returned after the run's end: it left (nodes.agent.watch)
EXIT_KILLED = 137  # (agent) a robot of a shared process killed by a fault: the code SIGKILL gives its own
# Stopped by a signal: 128 + its number (130 SIGINT, 143 SIGTERM), the code a
# shell reports for a process that signal kills. A signal that comes while the
# process still imports its modules (its first second or so, before main()
# installs the handlers) does kill it, so the shell sees the same code then.
EXIT_CODES_HELP = """\
exit codes:
  0    the run ended (the world said done, or left after the run started)
  1    the Zenoh session, or the logger's recording, could not be opened
       (e.g. the --listen port is taken)
  2    bad flags or scenario
  3    the router or the peers did not appear within --peers-timeout
  4    (agent) this robot already has an agent in the run;
       (world) the run already has a world
  5    (agent) its controller hung: a call of it had not returned 2 s after
       the run's end (nor in twice its longest step); it left without it
  130  stopped by SIGINT (Ctrl-C)
  143  stopped by SIGTERM"""
DUPLICATE_QUERY_S = 1.0  # how long the start-up check for another agent or world of the run waits
DEFAULT_PEERS_TIMEOUT_S = 60.0
MAX_PEERS_TIMEOUT_S = 1e6  # 11 days: beyond, a deadline overflows the clock's timestamps
# Zenoh's own connect timeout is set this much past ours, so that ours, which
# names what is missing, is the one that fires.
CONNECT_MARGIN_S = 2.0


def seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (0 < value <= MAX_PEERS_TIMEOUT_S):
        raise argparse.ArgumentTypeError(f"must be a number of seconds in (0, {MAX_PEERS_TIMEOUT_S:g}], got {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser, waits_for: str) -> None:
    """``--peers-timeout``; ``waits_for`` names the peers in its help."""
    parser.add_argument(
        "--peers-timeout",
        type=seconds,
        default=DEFAULT_PEERS_TIMEOUT_S,
        metavar="S",
        help=f"give up (exit code 3) when the router or {waits_for} have not appeared within S seconds "
        f"of the start (default {DEFAULT_PEERS_TIMEOUT_S:g})",
    )


def open_session(conf: zenoh.Config, stop: StopEvent, deadline: float) -> zenoh.Session | None:
    """``zenoh.open(conf)`` on a thread of its own, waited for until ``deadline``
    (``time.monotonic()``) or a stop signal. Returns the session, or None when
    stopped first; raises TimeoutError at the deadline and zenoh.ZError when
    Zenoh refuses the configuration."""
    import zenoh

    zenoh.try_init_log_from_env()  # Zenoh's own log on stderr, only if RUST_LOG asks for it
    done = threading.Event()
    lock = threading.Lock()
    box: dict[str, object] = {}

    def opener() -> None:
        try:
            sess = zenoh.open(conf)
        except zenoh.ZError as exc:
            box["error"] = exc
            done.set()
            return
        with lock:
            abandoned = box.get("abandoned", False)
            if not abandoned:
                box["session"] = sess
        if abandoned:
            sess.close()
        done.set()

    threading.Thread(target=opener, name="zenoh-open", daemon=True).start()
    stop.add_waker(done.set)
    wait_for(done, max(0.0, deadline - time.monotonic()) if math.isfinite(deadline) else None)
    with lock:
        if "session" in box:
            return box["session"]  # type: ignore[return-value]
        if "error" in box:
            raise box["error"]  # type: ignore[misc]
        box["abandoned"] = True
    if stop.is_set():
        return None
    raise TimeoutError


# What a process that hears no peer asks its user to check: a login or
# certificate of another run or role still connects (mTLS, access rules) but
# is handed nothing.
CHECK_PEERS = "check --run and --connect, and with --auth that its login and certificate are this run's and this role's"


def describe_session(args: argparse.Namespace) -> str:
    """Where a session from the common Zenoh flags is, for a report line."""
    if args.zenoh_mode == "client":
        return "connected to " + (", ".join(args.connect) or f"the endpoints of {args.config}")
    parts = [f"{args.zenoh_mode}"]
    if args.listen:
        parts.append(f"listening on {', '.join(args.listen)}")
    if args.connect:
        parts.append(f"linked to {', '.join(args.connect)}")
    if not args.listen and not args.connect and args.config:
        parts.append(f"endpoints of {args.config}")
    return ", ".join(parts)


class Process:
    """One role process: its name in what it prints, its stop signals and its
    peers deadline, which starts now. ``stop``: the stop event of a process
    that runs several roles (robots sharing a process), installed once."""

    def __init__(self, name: str, peers_timeout_s: float, stop: StopEvent | None = None) -> None:
        self.name = name
        self.peers_timeout_s = peers_timeout_s
        self.deadline = time.monotonic() + peers_timeout_s
        self.stop = install_stop_handlers() if stop is None else stop

    # One write per line: the robots that share a process print from threads of their own.
    def say(self, text: str) -> None:
        sys.stdout.write(f"{self.name}: {text}\n")
        sys.stdout.flush()

    def complain(self, text: str) -> None:
        sys.stderr.write(f"{self.name}: {text}\n")
        sys.stderr.flush()

    def gave_up(self, what: str) -> int:
        """Report missing peers; the exit code to return."""
        self.complain(f"gave up after {self.peers_timeout_s:g} s: {what}")
        return EXIT_NO_PEERS

    def stopped_by(self) -> str:
        """ "stopped by SIGTERM", for a report line."""
        return f"stopped by {signal.Signals(self.stop.signum).name}" if self.stop.signum else "stopped"

    def follower_end(self, run_id: str, done: bool, started: bool) -> tuple[int, str]:
        """The exit code and end note of a process that follows the world (an
        agent, the logger) once its loop ends: the world said done, a stop
        signal came, or the world left (before the run started: it gave up)."""
        if done:  # a process that heard nothing of the run before says so: it took no part
            return EXIT_OK, "the world said done" + ("" if started else " before any message of the run reached it")
        if self.stop.is_set():
            return self.stop.exit_code, self.stopped_by() + ("" if started else " before the run started")
        if not started:
            self.complain(f"the world of run {run_id!r} left before the run started; see its output")
            return EXIT_NO_PEERS, "the world left before the run started"
        return EXIT_OK, "the world left"

    def _open(self, args: argparse.Namespace, conf: zenoh.Config) -> zenoh.Session | None:
        """:func:`open_session`; with ``--auth-once`` the login is deleted once
        read, whether the session opened or not (it is of no use again)."""
        from formation_swarm.protocol import trust

        try:
            return open_session(conf, self.stop, self.deadline)
        finally:
            if getattr(args, "auth_once", False) and args.auth:
                trust.forget_login(args.auth)

    def left_s(self) -> float:
        return self.deadline - time.monotonic()

    def load(self, args: argparse.Namespace) -> Scenario | int:
        """The scenario of ``--scenario`` (``--run`` checked too), or the exit code after saying why not."""
        from formation_swarm.protocol.keys import check_run_id
        from formation_swarm.spec import scenario as scenario_mod

        try:
            check_run_id(args.run)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", scenario_mod.ScenarioWarning)
                sc = scenario_mod.load(args.scenario)
        except ValueError as exc:
            self.complain(str(exc))
            return EXIT_USAGE
        # One line each, in the role's words (Python's own format reads the
        # source file for the line that warned: for 100 agents, 100 times).
        for w in caught:
            if issubclass(w.category, scenario_mod.ScenarioWarning):
                self.complain(f"scenario warning: {w.message}")
            else:
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        return sc

    def connect(self, args: argparse.Namespace, login: str | None = None) -> zenoh.Session | int:
        """The Zenoh session of the common flags, open, or the exit code after
        saying why not (bad flags, no router by the deadline, a stop signal).
        ``login``: the user this role's --auth must log in as (swarm secure
        writes it as LOGIN.json); another's is refused before connecting: the
        router would let the process in, and its rules keep it from the keys
        it needs, so it would wait for a run it can take no part in."""
        import zenoh

        from formation_swarm.protocol import session, trust

        # Without a deadline (the router), Zenoh's own connect timeout stays the default.
        timeout_s = self.peers_timeout_s + CONNECT_MARGIN_S if math.isfinite(self.peers_timeout_s) else 30.0
        try:
            if login is not None and args.auth:
                user = trust.login_user(trust.read_settings(args.auth))
                if user is not None and user != login:
                    raise ValueError(
                        f"--auth {args.auth}: this login is for {user}, not for {login}: give "
                        f"{login}.json of the run's swarm secure"
                    )
            conf = session.config_from_args(args, connect_timeout_s=timeout_s)
        except ValueError as exc:
            self.complain(str(exc))
            return EXIT_USAGE
        try:
            sess = self._open(args, conf)
        except TimeoutError:
            where = ", ".join(args.connect) or f"the endpoints of {args.config}"
            return self.gave_up(
                f"no router answered at {where}; check --connect, that the router runs, and --auth "
                "(a router with logins refuses a process without its own)"
            )
        except zenoh.ZError as exc:
            self.complain(f"cannot open the Zenoh session: {session.zenoh_reason(exc)}")
            return EXIT_FAILED
        if sess is None:
            where = ", ".join(args.connect or args.listen) or f"the endpoints of {args.config}"
            self.say(f"{self.stopped_by()} while connecting to {where}")
            return self.stop.exit_code
        return sess
