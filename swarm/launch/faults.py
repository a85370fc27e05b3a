"""The scenario's faults as the launcher sees them: it executes the process
faults the world calls (``Keys.faults``, a FaultCall at the fault's tick):
SIGKILL, a fresh agent for the same robot, SIGSTOP, SIGCONT (a robot
that shares a process: a call to that process, launch.sharing); it says on the
console when the run passes each other fault's start and end."""

from __future__ import annotations

import queue
from collections.abc import Callable
from typing import TYPE_CHECKING

from formation_swarm.common.faults import Fault
from formation_swarm.launch.processes import Processes
from formation_swarm.launch.record import Journal, StatusFeed
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.messages import FaultCall

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

DONE = {"kill": "killed", "start": "started", "freeze": "frozen", "thaw": "thawed"}
RUN_END = "the run's end"  # why a process still frozen when the world says "done" is thawed


class FaultExecutor:
    """Executes the world's fault calls on the run's processes; ``restart``
    starts a fresh process for a scenario's process and returns its name."""

    def __init__(self, sc: Scenario, procs: Processes, journal: Journal, restart: Callable[[str], str]) -> None:
        self.sc = sc
        self.procs = procs
        self.journal = journal
        self.restart = restart
        self.calls: queue.SimpleQueue[bytes] = queue.SimpleQueue()  # the world's fault calls
        self.rejections = Rejections()
        self.last_seq = 0
        self.said: set[tuple[str, int]] = set()  # the link/sensor/actuator faults' starts and ends said

    def put(self, payload: bytes) -> None:  # a Zenoh thread: hands over only
        self.calls.put(payload)

    def execute_calls(self) -> None:
        """The world's fault calls that have come, in order: a signal, or a fresh agent."""
        while True:
            try:
                payload = self.calls.get_nowait()
            except queue.Empty:
                return
            call = self.rejections.decode(FaultCall, payload)
            if call is None:
                continue
            faults = self.sc.faults
            if call.index >= len(faults) or faults[call.index].process != call.process:
                self.rejections.reject("not a fault of the schedule")
                continue
            if call.seq <= self.last_seq:
                self.rejections.reject("replayed or reordered")
                continue
            self.last_seq = call.seq
            self._execute(call, faults[call.index])

    def _execute(self, call: FaultCall, fault: Fault) -> None:
        procs = self.procs
        if call.action == "start":
            name = self.restart(call.process)
        else:
            name = procs.act(call.process, call.action)
            procs.frozen_by[call.process if name in procs.shared else name] = str(fault)
        # A robot of a shared process is named, with that process beside it.
        where = {"process": name} if name not in procs.shared else {"process": call.process, "in_process": name}
        done = DONE[call.action]
        self._say_windows_until(call.tick)  # the world is at the call's tick: what came before, first
        self.journal.add(
            done,
            **where,
            fault=str(fault),
            tick=call.tick,
            sim_time_s=call.time_s,
            wall_s=self.journal.wall_s(),
            pid=procs.children[name].pid,
        )
        self.journal.say(
            f"[swarm] {done} {where['process']} at tick {call.tick}, sim t={call.time_s:.2f} s ('{fault}')"
        )

    def say_windows(self, status: StatusFeed) -> None:
        """The schedule's faults the world applies itself (link, sensor, actuator):
        a line when the run passes each one's start and end, as the process
        faults get when they are carried out (as soon as a status says the
        tick is passed: up to a status period late)."""
        if status.last is not None:
            self._say_windows_until(status.last.tick)

    def _say_windows_until(self, tick: int) -> None:
        """The window faults' starts and ends up to ``tick`` not said yet, in
        tick order: a process fault's call at a later tick comes after them."""
        dt = self.sc.dt_s
        due = []
        for i, f in enumerate(self.sc.faults):
            if f.process is not None:
                continue
            start, end = f.start_tick(dt), f.end_tick(dt)
            if tick >= start and ("on", i) not in self.said:
                due.append((start, i, "on", f))
            if end is not None and tick >= end and ("off", i) not in self.said:
                due.append((end, i, "off", f))
        for at, i, what, f in sorted(due, key=lambda d: d[:2]):
            self.said.add((what, i))
            self.journal.say(f"[swarm] fault {what} from tick {at}, sim t={at * dt:.2f} s ('{f}')")

    def thaw_at_end(self, status: StatusFeed) -> None:
        """Once the world has said "done", a process still frozen by a fault that
        outlasts the run is thawed: it could not leave, and the world and the
        followers would wait for it (the logger: up to 10 s)."""
        procs = self.procs
        if not procs.frozen or not status.done:
            return
        st = status.last
        assert st is not None  # done
        for name in sorted(procs.frozen):
            procs.thaw(name)
            self.journal.add(
                "thawed",
                process=name,
                fault=procs.frozen_by.get(name),
                why=RUN_END,
                sim_time_s=st.time_s,
                tick=st.tick,
                wall_s=self.journal.wall_s(),
            )
            self.journal.say(f"[swarm] thawed {name} at the run's end (its freeze outlasted the run)")
        procs.frozen.clear()
