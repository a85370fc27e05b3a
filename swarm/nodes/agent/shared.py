"""Several robots' agents in one process (``swarm run`` with
``run.agents_per_process`` above 1): a robot's agent each, on a thread of its own.

    python -m formation_swarm.nodes.agent.shared --control FILE -- AGENT-FLAGS [-- AGENT-FLAGS ...]

Each ``AGENT-FLAGS`` is one robot's ``swarm agent`` command line (its id,
stats, spool, login). Each robot keeps what a process of its own has: its
Zenoh session opened with its own login (a stolen login does no more than
its robot), its liveliness token, its role, EKF, controller and clock, its
stats file; what they share is the interpreter (one import, one CPU cache,
one process for the scheduler to wake). A stop signal stops every robot.

A process fault on one robot acts on that robot alone. The launcher appends
its calls to ``--control``, one line each, ``SEQ ACTION ROBOT`` (kill,
freeze, thaw), and wakes this process with CALL_SIGNAL, on which they are
read at once (and every CONTROL_PERIOD_S besides): a kill closes the robot's
session (its token goes: the world sees it die) and nothing more of it is
sent or written; a freeze holds its loop (its messages wait in its inbox;
its session stays, so the Zenoh lease never ends it) until the thaw. A
restart is the launcher's: a fresh process for the robot alone. A robot
whose controller hangs past the run's end takes the process, and so its
neighbours, with it (nodes.agent.watch): they are done by then.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
import traceback
from pathlib import Path

from formation_swarm.nodes.agent import main as agent_main
from formation_swarm.nodes.agent.node import Agent
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime.proc import exit_after_main, install_stop_handlers

SEPARATOR = "--"  # between the robots' command lines
# The launcher signals each call (launch.sharing.CALL_SIGNAL): its fault lands at once. The
# file is read every CONTROL_PERIOD_S besides; a wake at 50 Hz cost a process of 10 robots
# 7-13 us of CPU per robot-tick (its main thread waits for the robots' interpreter lock).
CALL_SIGNAL = signal.SIGUSR1
CONTROL_PERIOD_S = 0.5
ACTIONS = ("kill", "freeze", "thaw")
MAX_LINE = 64  # a control line is "SEQ ACTION ROBOT": anything longer is not one


def split_argv(argv: list[str]) -> tuple[list[str], list[list[str]]]:
    """This process's own flags and each robot's, split at ``--``."""
    groups: list[list[str]] = [[]]
    for arg in argv:
        if arg == SEPARATOR:
            groups.append([])
        else:
            groups[-1].append(arg)
    return groups[0], [g for g in groups[1:] if g]


class Robots:
    """The robots' agents by id, as they are made; executes the control calls."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.agents: dict[int, Agent] = {}
        self.lock = threading.Lock()
        self.last_seq = 0
        self.rejected = 0

    def made(self, agent: Agent) -> None:
        with self.lock:
            self.agents[agent.brain.robot_id] = agent

    def execute(self, line: str) -> None:
        """One control line, checked: a sequence number above the last, a known action and robot."""
        parts = line.split()
        ok = len(line) <= MAX_LINE and len(parts) == 3 and parts[0].isdigit() and parts[2].isdigit()
        if not ok or int(parts[0]) <= self.last_seq or parts[1] not in ACTIONS:
            self._reject(f"not a control call: {line[:MAX_LINE]!r}")
            return
        self.last_seq = int(parts[0])
        with self.lock:
            agent = self.agents.get(int(parts[2]))
        if agent is None:
            self._reject(f"{parts[1]} of robot {parts[2]}: no robot of this process by that id")
        elif parts[1] == "kill":
            agent.kill()
        else:
            agent.freeze(parts[1] == "freeze")

    def _reject(self, why: str) -> None:
        self.rejected += 1
        print(f"{self.name}: {why}; ignored", file=sys.stderr, flush=True)


class ControlFile:
    """The new whole lines of the launcher's control file since the last read."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.offset = 0
        self.partial = b""

    def read(self) -> list[str]:
        try:
            with self.path.open("rb") as f:
                f.seek(self.offset)
                data = f.read(64 * 1024)
        except FileNotFoundError:
            return []  # no call yet
        self.offset += len(data)
        *lines, self.partial = (self.partial + data).split(b"\n")
        if len(self.partial) > MAX_LINE:  # never a line's end: not the launcher's
            self.partial = b""
        return [raw.decode("utf-8", "replace") for raw in lines]


class Calls:
    """The launcher's calls, read and executed on its signal and on the main
    loop's reads; a signal that lands during a read is a read again after it."""

    def __init__(self, control: ControlFile, robots: Robots) -> None:
        self.control = control
        self.robots = robots
        self.busy = False
        self.again = False

    def read(self, _sig: int | None = None, _frame: object = None) -> None:
        if self.busy:  # a signal handler between two lines of this same read (main thread only)
            self.again = True
            return
        self.busy = self.again = True
        try:
            while self.again:
                self.again = False
                for line in self.control.read():
                    self.robots.execute(line)
        finally:
            self.busy = False


def main(argv: list[str] | None = None) -> int:
    own, groups = split_argv(list(sys.argv[1:] if argv is None else argv))
    ap = argparse.ArgumentParser(prog="python -m formation_swarm.nodes.agent.shared", description=__doc__)
    ap.add_argument("--control", required=True, metavar="FILE", help="the launcher's fault calls, a line each")
    opts = ap.parse_args(own)
    parser = agent_main.build_parser()
    robots = [parser.parse_args(g) for g in groups]
    ids = [a.id for a in robots]
    name = f"agents {','.join(map(str, ids))}"
    if not robots or len(set(ids)) != len(ids):
        print(f"{name}: give each robot's agent flags once, after {SEPARATOR}", file=sys.stderr, flush=True)
        return process_mod.EXIT_USAGE
    stop = install_stop_handlers()
    # One scenario for all (its warnings said once): each robot's flags name the same.
    sc = process_mod.Process(name, robots[0].peers_timeout, stop=stop).load(robots[0])
    if isinstance(sc, int):
        return sc
    shared = Robots(name)
    codes: dict[int, int] = {}

    def one(args: argparse.Namespace) -> None:
        role = process_mod.Process(f"agent {args.id}", args.peers_timeout, stop=stop)
        try:
            codes[args.id] = agent_main.serve(args, role, share=len(robots), made=shared.made, sc=sc)
        except Exception:  # noqa: BLE001 - one robot's failure, told with its traceback; the others fly on
            role.complain(f"failed:\n{traceback.format_exc()}")
            codes[args.id] = process_mod.EXIT_FAILED

    calls = Calls(ControlFile(Path(opts.control)), shared)
    signal.signal(CALL_SIGNAL, calls.read)  # before any robot can be called
    threads = [threading.Thread(target=one, args=(a,), name=f"agent-{a.id}") for a in robots]
    for t in threads:
        t.start()
    while any(t.is_alive() for t in threads):
        calls.read()
        time.sleep(CONTROL_PERIOD_S)  # the signal's handler runs within the sleep
    # A killed robot ended as the launcher asked: it fails nothing here.
    failed = [c for c in codes.values() if c not in (process_mod.EXIT_OK, process_mod.EXIT_KILLED)]
    return failed[0] if failed else process_mod.EXIT_OK


if __name__ == "__main__":
    exit_after_main(main())
