"""The run's processes (this machine's children and the hosts' agents, one
interface): started, signalled, watched for an exit with an error, and at
the end stopped and always reaped."""

from __future__ import annotations

import contextlib
import functools
import signal
import subprocess
import time
from collections.abc import Callable, Sequence

from formation_swarm.launch import sharing
from formation_swarm.launch.record import Journal
from formation_swarm.launch.remote import RemoteChild
from formation_swarm.runtime import spawner
from formation_swarm.runtime.children import KILLED_AT_STOP_TIMEOUT, Child, describe_exit, log_tail
from formation_swarm.runtime.process import EXIT_HUNG

SIGNALS = {"kill": signal.SIGKILL, "freeze": signal.SIGSTOP, "thaw": signal.SIGCONT}
END_GRACE_S = 3.0  # at the end, the processes' time to leave on the world's "done"
STOP_GRACE_S = 2.0  # after SIGTERM, before SIGKILL (plus a second)
REAP_WAIT_S = 5.0


def wait_for_fork_server() -> None:
    """Return once the fork server answers: it imports the roles' modules
    first (seconds on a busy machine), and a role's start waits for it with
    a Ctrl-C held back (a start cut in two would leave a process nobody
    knows). Here the server forks a child that does nothing, and a Ctrl-C
    may cut the wait: nothing is left half started."""
    import multiprocessing

    spawner.warm()
    probe = multiprocessing.get_context("forkserver").Process(target=int, name="fork-server-probe", daemon=True)
    probe.start()
    probe.join()


class Processes:
    """The run's processes by name. A process of the scenario (agent-3) may
    have had several children: ``current`` names its newest (agent-3.2)."""

    def __init__(self, journal: Journal) -> None:
        self.journal = journal
        self.children: dict[str, Child] = {}
        self.current: dict[str, str] = {}  # a process of the scenario -> its newest child (agent-3 -> agent-3.2)
        self.frozen: set[str] = set()  # children stopped by SIGSTOP, robots of a shared process frozen
        self.shared: dict[str, sharing.Control] = {}  # a process of several robots -> its calls
        self.sharer: dict[str, str] = {}  # a robot started in a shared process -> that process (agent-3 -> agents-2-11)
        self.frozen_by: dict[str, str] = {}  # the fault that froze (or thawed) each, last

    def start(self, child: Child) -> str:
        """Start ``child`` as its process's newest; its name."""
        self.children[child.name] = child
        self.current[child.name.split(".")[0]] = child.name
        if robots := sharing.robots_in(child.argv):
            wake = functools.partial(child.signal, sharing.CALL_SIGNAL)
            self.shared[child.name] = sharing.Control(sharing.control_path(child.argv), wake)
            self.current.update(dict.fromkeys(robots, child.name))
            self.sharer.update(dict.fromkeys(robots, child.name))
        child.start()
        return child.name

    def act(self, process: str, action: str) -> str:
        """Kill, freeze or thaw ``process`` (agent-3): its newest child by a signal,
        or in a shared process that robot alone by a call; the child's name."""
        name = self.current[process]
        if name in self.shared:
            self.shared[name].call(action, process)
            held = process
        else:
            self.children[name].signal(SIGNALS[action])
            held = name
        (self.frozen.add if action == "freeze" else self.frozen.discard)(held)
        return name

    def thaw(self, held: str) -> None:
        """A name of ``frozen`` thawed: a child's SIGCONT, or a robot's call."""
        if held in self.children:
            self.children[held].signal(signal.SIGCONT)
        elif (name := self.current.get(held)) in self.shared:
            self.shared[name].call("thaw", held)

    def first_argv(self, process: str) -> list[str]:
        """The command line ``process`` (agent-3) was first started with, alone
        (a robot of a shared process: the one it would have had)."""
        if process in self.sharer:
            return sharing.robots_in(self.children[self.sharer[process]].argv)[process]
        return self.children[process].argv

    def newest(self, process: str) -> Child:
        return self.children[self.current[process]]

    def next_name(self, process: str) -> str:
        """The name of ``process``'s next child: agent-3.2, agent-3.3, ..."""
        n = 2
        while f"{process}.{n}" in self.children:
            n += 1
        return f"{process}.{n}"

    def kill_and_reap(self, child: Child) -> None:
        """SIGKILL and wait (a restart: the old one's token must be gone first).
        A shared process lives on: its robot was killed at the kill call."""
        if child.proc is not None and child.name not in self.shared:
            child.signal(signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                child.proc.wait(timeout=REAP_WAIT_S)

    def pids(self) -> dict[str, int]:
        return {n: c.pid for n, c in self.children.items() if c.pid is not None}

    def failed_to_start(self) -> list[str]:
        """The children that ended with an error though no one stopped them."""
        return [c.name for c in self.children.values() if c.poll() not in (None, 0) and c.stop_sent_at is None]

    def report_exits(self, t: float, started: bool, lost_hosts: Sequence[str]) -> None:
        """Every child that ended since the last look with an error, on its own:
        an event, and on the console which one, how, and the last lines of its
        log. ``t``: the sim time; ``started``: the run has passed tick 0."""
        for child in self.children.values():
            code = child.poll()
            if code is not None and not child.reported:
                child.reported = True
                if code != 0 and child.stop_sent_at is None:
                    self._exited(child, code, t, started, lost_hosts)

    def _exited(self, child: Child, code: int, t: float, started: bool, lost_hosts: Sequence[str]) -> None:
        events = self.journal.events
        if isinstance(child, RemoteChild) and child.host in lost_hosts:
            # Its exit code stayed on that host (remote.LOST_CODE stands for it here): none is made up.
            self.journal.add("exited", process=child.name, sim_time_s=t, host_lost=child.host)
            return
        kill = next((e for e in events if e["event"] == "killed" and e["process"] == child.name), None)
        if kill is not None:
            # By fault injection, already said; it died at the kill (the status may lag behind).
            at = kill.get("sim_time_s", t)
            self.journal.add("exited", process=child.name, code=code, sim_time_s=at, tick=kill.get("tick"))
            return
        tail = log_tail(child.log_path)
        self.journal.add("exited", process=child.name, code=code, sim_time_s=t, log_tail=tail)
        if code == EXIT_HUNG and child.name.startswith("agent-"):
            return  # it left at the run's end without its hung controller: the summary's failure says it
        # Seen now; the world's last status lags (by seconds of sim time in lockstep):
        # the summary places it at the tick the world saw it go (result.place_exits).
        when = f"during the run (the world's last status: sim t={t:.2f} s)" if started else "before the run started"
        self.journal.say(f"[swarm] {child.name} {describe_exit(code)} {when}; the end of {child.log_path}:")
        for line in tail or ["(the log is empty)"]:
            self.journal.say(f"  | {line}")

    def stop(self, graceful_first: bool, cut_short: Callable[[], bool] = lambda: False) -> None:
        """Give everyone END_GRACE_S to leave on the world's "done" (with
        ``graceful_first``, until ``cut_short`` says otherwise), then SIGTERM,
        then SIGKILL after STOP_GRACE_S; reap every child and close its log."""
        for name in self.frozen:  # a stopped process hears no SIGTERM, nor the end of the run
            self.thaw(name)
        self.frozen.clear()
        if graceful_first:
            self._wait_exit(END_GRACE_S, cut_short)
        for c in self.children.values():
            c.signal(signal.SIGTERM)
        self._wait_exit(STOP_GRACE_S + 1.0)
        for c in self.children.values():
            if c.poll() is None:
                self.journal.add(KILLED_AT_STOP_TIMEOUT, process=c.name)
                c.signal(signal.SIGKILL)
        for c in self.children.values():
            if c.proc is not None:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    c.proc.wait(timeout=REAP_WAIT_S)
                c.poll()
            c.close()

    def note_unreported_codes(self) -> None:
        """Events for the exit codes the fork server did not report (taken from the child's record)."""
        for child in self.children.values():
            if getattr(child.proc, "unreported", False):
                code = child.proc.returncode  # type: ignore[union-attr]
                self.journal.add("exit code not reported by the fork server", process=child.name, code=code)

    def _wait_exit(self, seconds: float, cut_short: Callable[[], bool] = lambda: False) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline and any(c.poll() is None for c in self.children.values()):
            if cut_short():
                return
            time.sleep(0.02)
