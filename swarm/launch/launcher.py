"""``swarm run``: one run, every robot its own process: start, watch, stop, reap.

The world (here also the Zenoh router on a free loopback port), the logger
and an agent per robot, or the agents on hosts (launch.hosts) and outside
ones (launch.external). Process faults come from the world's calls
(launch.faults). What a run's ending means: launch.result; the run folder
and its console: docs/running.md.
"""

from __future__ import annotations

import dataclasses
import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import zenoh

from formation_swarm.launch import external as external_mod
from formation_swarm.launch import mainguard, remote, result, sharing, summarize
from formation_swarm.launch import ros2 as ros2_mod
from formation_swarm.launch.console import print_result, progress_line, reachable_live
from formation_swarm.launch.faults import FaultExecutor
from formation_swarm.launch.hosts import HostOptions, Hosts
from formation_swarm.launch.logins import RunLogins
from formation_swarm.launch.plan import SECRETS, KillAt, Plan, RunOptions
from formation_swarm.launch.processes import Processes, wait_for_fork_server
from formation_swarm.launch.record import Journal, StatusFeed, folder_identity
from formation_swarm.launch.result import Ending, RunResult, fetch_failed_logs, place_exits
from formation_swarm.launch.signals import stop_signals_noted
from formation_swarm.nodes.logger import viewer
from formation_swarm.protocol import acl
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.session import make_config
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.children import Child, free_port
from formation_swarm.runtime.process import DEFAULT_PEERS_TIMEOUT_S

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

# What a run's user takes from here: the run, its options and result, how it
# prints, and (for tests that start processes of their own) a free port.
__all__ = ["KillAt", "Launch", "RunResult", "free_port", "print_result"]

_HOST_KEYS = frozenset(f.name for f in dataclasses.fields(HostOptions))
_RUN_KEYS = frozenset(f.name for f in dataclasses.fields(RunOptions))
PROGRESS_PERIOD_S = 2.0  # between two progress lines
LOOK_PERIOD_S = 0.05  # between two looks at the processes while waiting


class Launch:
    """One run. Use as a context manager: leaving it always stops and reaps.

    ``Launch(scenario, **options)``: a shipped scenario's name or a TOML
    file, and the keywords of :class:`~formation_swarm.launch.plan.RunOptions`
    (mode, seed, out, overrides, logger, faults, ...) and, for agents on
    other machines, of :class:`~formation_swarm.launch.hosts.HostOptions`.
    Every option is checked here, before anything starts (ValueError)."""

    def __init__(self, scenario_path: str | Path, **options: Any) -> None:
        for key in options:
            if key not in _RUN_KEYS | _HOST_KEYS:
                raise TypeError(f"Launch() got an unexpected keyword argument {key!r}")
        run = RunOptions(**{k: v for k, v in options.items() if k in _RUN_KEYS})
        self.plan = Plan.make(scenario_path, run)
        self.journal = Journal(run.progress or (lambda line: print(line, flush=True)))
        for warning in self.sc.warnings:  # the loader's, with the run's other console lines
            self.journal.say(f"[swarm] warning: {warning}")
        self.plan.check_process_faults()
        self.procs = Processes(self.journal)
        self.status = StatusFeed()
        self.faults = FaultExecutor(self.sc, self.procs, self.journal, self._restart)
        host_options = HostOptions(**{k: v for k, v in options.items() if k in _HOST_KEYS})
        self.hosts = Hosts(host_options, self.plan, self.journal, self.procs)
        if self.plan.external and self.hosts.names:
            raise ValueError("external robots and hosts: not together; an outside agent connects to this machine")
        if self.hosts.names and sharing.per_process(self.sc) > 1:
            raise ValueError("run.agents_per_process above 1 and hosts: not together; a host starts one agent each")
        self.port = 0
        self.logins: RunLogins | None = None  # the run's, once written (prepare)
        self.external: dict[int, external_mod.ExternalAgent] = {}  # robot -> what its outside agent needs (prepare)
        self.outside: external_mod.Outside | None = None  # their tokens watched (start)
        self.session: zenoh.Session | None = None
        self.token: zenoh.LivelinessToken | None = None  # held: a dropped token is undeclared
        self._interrupt = threading.Event()  # interrupt(): another thread's Ctrl-C (a sweep's runs)
        self.said_web = False  # the web viewer's address is on the console
        self.folder_id: tuple[int, int] | None = None  # the run folder's (device, inode)

    # -- what the run is ------------------------------------------------------------
    @property
    def sc(self) -> Scenario:
        """The scenario as run."""
        return self.plan.sc

    @property
    def run_id(self) -> str:
        return self.plan.run_id

    @property
    def run_dir(self) -> Path:
        return self.plan.run_dir

    @property
    def web_ports(self) -> tuple[int, int]:
        return self.plan.options.web_ports

    @property
    def explicit(self) -> dict[int, str]:
        """robot -> host: the placement asked for (the scenario's, then ``placement``)."""
        return self.hosts.explicit

    @property
    def children(self) -> dict[str, Child]:
        """Every process started, by name (agent-3, and a fresh one agent-3.2)."""
        return self.procs.children

    @property
    def endpoint(self) -> str:
        """Where this machine's processes reach the router (the world, or with
        hosts the launcher, which listens on ``listen`` for the hosts too)."""
        return f"tcp/127.0.0.1:{self.port}"

    def pids(self) -> dict[str, int]:
        return self.procs.pids()

    def login(self, user: str) -> dict[str, Any] | None:
        """The Zenoh settings of ``user``'s login in this run (world, logger,
        launcher, agent-N; None without auth), from the launcher's memory: the
        files are gone once their process has read them."""
        found = None if self.logins is None else self.logins.settings.get(user)
        return None if found is None else dict(found)

    def sim_time(self) -> float:
        """The sim time the world last said, in s; -1 before its first status."""
        return self.status.sim_time()

    # -- lifecycle ----------------------------------------------------------------
    def __enter__(self) -> Launch:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self, announce: Callable[[], None] | None = None) -> None:
        """Spawn every process (once), after ``announce()`` if given; on any failure
        (Ctrl-C included, in ``announce`` too) reap what started and write the summary."""
        if self.children:
            return
        if self.plan.options.fork:  # its children import the main script again: refused unguarded
            mainguard.check()
        try:
            if announce is not None:  # a Ctrl-C its reader sends at once lands here, not before the summary's guard
                announce()
            self._start()
        except BaseException as exc:
            host_failed = isinstance(exc, (remote.HostError, ValueError))  # a host missing, refusing, unfit
            try:
                self._watch()  # a child that already failed (the world, say) explains itself
                self.stop(graceful_first=False)
            finally:  # the summary, whatever the reaping met (a second Ctrl-C included)
                if host_failed:
                    self.journal.add("start failed", why=str(exc))
                if self.run_dir.exists():
                    summarize.write(self, 1 if host_failed else 130, Ending(interrupted=not host_failed))
            raise

    def prepare(self) -> dict[int, external_mod.ExternalAgent]:
        """The run's folder, port and logins, made once, before any process starts
        (start() does it if not done): what each outside agent needs, by robot,
        known before the router exists. Writes the observer's login if asked."""
        if self.logins is None:
            plan = self.plan
            scenario = plan.make_folder()
            self.folder_id = folder_identity(self.run_dir)
            self.port = free_port()
            written = plan.write_logins(
                world="loopback" if self.hosts.names else "router", host_logins=self.hosts.logins, tls=self.hosts.tls
            )
            self.logins = RunLogins.kept(written)
            self.external = external_mod.slots(
                plan.external, endpoint=self.endpoint, run_id=self.run_id, scenario=scenario, logins=written
            )
            if (target := plan.options.observer_login) is not None and written:
                external_mod.write_observer_login(written[acl.OBSERVER], Path(target))
        return self.external

    def _start(self) -> None:
        plan, remote_agents = self.plan, bool(self.hosts.names)
        if plan.options.fork:
            wait_for_fork_server()
        self.prepare()
        logins = self.logins or RunLogins()
        secrets = logins.files
        if remote_agents:
            self.session = self.hosts.open_router(self.endpoint, secrets)
        lines = plan.command_lines(
            self.endpoint,
            secrets,
            remote_agents=remote_agents,
            live=reachable_live(self.plan.options.live, self.journal.say),
        )
        logins.forget_unread(lines.values(), keep=[a.login for a in self.external.values()])
        self.journal.started_at = time.monotonic()
        for name, argv in lines.items():
            self.procs.start(Child(name, argv, plan.log_path(name), fork=plan.options.fork))
        wait = self.plan.options.peers_timeout_s or DEFAULT_PEERS_TIMEOUT_S
        ends = {"endpoint": self.endpoint, "observer_login": self.plan.options.observer_login, "run_id": self.run_id}
        external_mod.hand_over(self.journal.say, self.external, wait, **ends)
        ros2_mod.hand_over(self.journal.say, plan, self.endpoint)
        if self.session is None:
            settings = logins.settings.get("launcher")
            self.session = zenoh.open(make_config("client", [self.endpoint], connect_timeout_s=30.0, settings=settings))
        keys = Keys(self.run_id)
        self.session.declare_subscriber(keys.status, lambda s: self.status.put(s.payload.to_bytes()))
        self.session.declare_subscriber(keys.faults, lambda s: self.faults.put(s.payload.to_bytes()))
        self.outside = external_mod.Outside(self.external, logins.settings, self.journal, keys)
        self.outside.listen(self.session)
        # After the subscriber: with process faults the world waits for this token before tick 0.
        self.token = self.session.liveliness().declare_token(keys.alive("launcher", 0))
        if remote_agents:
            self.hosts.start(self.session, logins.settings)

    def _restart(self, process: str) -> str:
        """A fresh process for ``process`` (an agent), as the first was started
        but with its own log and stats file; its name (agent-3.2, ...)."""
        old = self.procs.newest(process)
        self.procs.kill_and_reap(old)  # SIGKILLed at the kill call: reaped first, so its token is gone
        name = self.procs.next_name(process)
        if isinstance(old, remote.RemoteChild):
            return self.hosts.restart(old, name)
        argv = self.plan.restart_argv(self.procs.first_argv(process), name)
        if self.logins is not None:
            self.logins.rewrite(process, argv)
        return self.procs.start(Child(name, argv, self.plan.log_path(name), fork=self.plan.options.fork))

    @property
    def interrupted(self) -> bool:
        """A Ctrl-C (SIGINT or SIGTERM, on the main thread) or :meth:`interrupt` came."""
        return self._interrupt.is_set()

    def interrupt(self) -> None:
        """Stop the run as a Ctrl-C would, from any thread: :meth:`wait` stops
        every process and ends with exit code 130, the summary ``interrupted``."""
        self._interrupt.set()

    def wait_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Poll ``predicate`` (and watch the children) until true or the timeout."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return True
            self._watch()
            if self.children["world"].poll() is not None:
                return predicate()
            time.sleep(0.02)
        return False

    def _watch(self) -> None:
        self.status.read()
        # The world's calls before the thaw at its end: a lockstep run may pass a
        # freeze's tick and end between two looks (20 ticks take 20 ms here), and
        # a freeze carried out after the thaw would hold its process to the end.
        self.faults.execute_calls()
        self.faults.say_windows(self.status)
        self.faults.thaw_at_end(self.status)
        t = self.sim_time()
        opts = self.plan.options
        if opts.serve_web and opts.logger and not self.said_web and self.status.last is not None:
            # The world starts once the logger is there, serving: the address works now.
            self.said_web = True
            self.journal.say(f"[swarm] watch the run in a browser: {viewer.web_address(*opts.web_ports)}")
        self.hosts.check_lost(t)
        if self.outside is not None:
            self.outside.look(self.status)
        fetch_failed_logs(self.children, self.run_dir / "stats")
        self.procs.report_exits(t, started=self.status.last is not None, lost_hosts=self.hosts.lost)

    def wait(self, timeout_s: float | None = None) -> RunResult:
        """Run to the end (or timeout/Ctrl-C), stop everything, write the summary."""
        ending, shown = self._follow(timeout_s)
        # From here a Ctrl-C cuts nothing short: it is noted, and the run ends interrupted.
        with stop_signals_noted(self.interrupt):
            return self._finish(ending, shown)

    def _finish(self, ending: Ending, shown: int | None) -> RunResult:
        self._watch()
        last = self.status.last
        if last is not None and last.tick != shown and not ending.interrupted:
            self.journal.say(progress_line(last))  # a run shorter than a line's 2 s showed only its start
        self.stop(graceful_first=not ending.abrupt)
        if self.interrupted and not ending.interrupted:  # while the processes left
            self.journal.say("[swarm] interrupted: every process stopped")
            ending = dataclasses.replace(ending, interrupted=True)
        self.procs.note_unreported_codes()
        world = self.children["world"]
        code = ending.exit_code(world.proc.returncode if world.proc is not None else None)
        parts = summary_mod.read_parts(self.run_dir / "stats")
        world_stats = parts.get("world", {})
        place_exits(self.journal.events, world_stats)
        if self.outside is not None:  # its losses, and every robot's login a second session used
            self.outside.settle(world_stats)
        events = self.journal.events
        lost = summary_mod.run_failed(parts, self.sc, events) or summary_mod.logger_lost(world_stats, events)
        if self.plan.external and (line := external_mod.gave_up(world_stats, events, self.plan)):
            self.journal.say(line)
        if code == 0 and lost:
            self.journal.say(f"[swarm] the run failed: {lost}")
            code = 1  # it ran to its end, but not as a formation, or not recorded whole: not a success
        if code in (0, 1) and self.hosts.lost:
            self.hosts.say_lost()
            code = 1
        summary = summarize.write(self, code, ending)
        if unkept := summary.get("unkept"):  # the folder deleted, or the disk full: said in one line
            self.journal.say(f"[swarm] the run failed: {unkept}")
            summary["exit_code"] = code = 1
        return RunResult(self.run_dir, summary, code, self.pids())

    def _follow(self, timeout_s: float | None) -> tuple[Ending, int | None]:
        """Watch the run until the world ends, a process fails before tick 0,
        the timeout or a Ctrl-C; how it ended and the tick last shown."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        last_line = 0.0
        shown: int | None = None  # the tick of the last progress line
        world = self.children["world"]
        try:
            while world.poll() is None:
                self._watch()
                now = time.monotonic()
                if self.status.last is None and (failed := self.procs.failed_to_start()):
                    self.journal.say(
                        f"[swarm] the run cannot start without {', '.join(failed)}: stopping every process"
                    )
                    return Ending(start_failed=True), shown
                if shown is None and self.status.first is not None:
                    # The run's start first, even when its end is already queued behind it
                    # (a short lockstep run may be over before this loop's first look).
                    self.journal.say(progress_line(self.status.first))
                    shown, last_line = self.status.first.tick, now
                elif now - last_line >= PROGRESS_PERIOD_S and self.status.last is not None:
                    self.journal.say(progress_line(self.status.last))
                    shown, last_line = self.status.last.tick, now
                if deadline is not None and now > deadline:
                    self.journal.say(f"[swarm] timeout after {timeout_s:g} s: stopping the run")
                    return Ending(timed_out=True, limit_s=timeout_s), shown
                if self._interrupt.wait(LOOK_PERIOD_S):
                    raise KeyboardInterrupt
        except KeyboardInterrupt:
            self.journal.say("[swarm] interrupted: stopping every process")
            return Ending(interrupted=True), shown
        return Ending(), shown

    def stop(self, graceful_first: bool = True) -> None:
        """End of run: give everyone END_GRACE_S to leave on the world's "done",
        then SIGTERM, then SIGKILL after STOP_GRACE_S. Always reaps: a Ctrl-C
        meanwhile does not interrupt the reaping, it ends the grace (and the
        run is :attr:`interrupted`)."""
        with stop_signals_noted(self.interrupt):
            self.procs.stop(graceful_first, cut_short=self._interrupt.is_set)
            self.hosts.stop()
            result.merge_wire(self.run_dir, self.journal.say)  # every receiver has left: its spool is whole
            if self.session is not None:
                self.session.close()
                self.session = None
            # Every process that held a password is gone: they are of no use now.
            shutil.rmtree(self.run_dir / SECRETS, ignore_errors=True)
