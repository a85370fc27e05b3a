"""The agent's watchdog: a thread that notes a controller call that does
not return, and ends the process when the run is over without it.

A controller that hangs in ``step`` (``while True: pass``, a lock never
released) holds the loop's thread: the agent answers nothing and cannot
leave on the run's end. This thread still runs (the interpreter hands the
GIL over every few milliseconds). Once a call has gone on for NOTE_AFTER_S
it writes the stats again with ``in_step`` (its tick, the call, its time so
far), every WATCH_PERIOD_S, and says it once in the log at LOG_AFTER_S.
When the run is over (the world said done, or a stop signal came) and the
call has still not returned HUNG_AFTER_END_S later, nor within twice the
longest step before it, the controller hung: the agent writes its last
stats and ends its process (runtime.process.EXIT_HUNG).
runtime.summary reads ``in_step`` as the controller's hang; so too for an
agent the launcher killed at its stop timeout, if this thread could not run.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Protocol

from formation_swarm.agents.step_times import StepTimes
from formation_swarm.nodes.agent.stats import StatsFile

WATCH_PERIOD_S = 0.5
NOTE_AFTER_S = 1.0  # a call this long is in the stats file
LOG_AFTER_S = 5.0  # and this long, in the log
HUNG_AFTER_END_S = 2.0  # a call not returned this long after the run's end, nor in twice the longest step, hung


class Watched(Protocol):
    """The process whose role's calls are watched (nodes.agent.node.Agent)."""

    def who(self) -> str:
        """What decides the robot's steps: "controller pkg.mod:Cls"."""
        ...

    def over(self) -> bool:
        """Whether the run is over: the world said done, or a stop signal came."""
        ...

    def complain(self, text: str) -> None:
        """A line in the process's log."""
        ...

    def leave_hung(self, call: dict[str, Any]) -> None:
        """End the process: ``call`` hung."""
        ...


class StepWatch:
    """Watches ``times`` (a role's): notes a long call in ``stats_file`` and
    in ``owner``'s log; once the run is over, hands a call that hung to
    ``owner.leave_hung``."""

    def __init__(self, times: StepTimes, stats_file: StatsFile, owner: Watched) -> None:
        self.times = times
        self.stats_file = stats_file
        self.owner = owner
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="step-watch", daemon=True)

    def __enter__(self) -> StepWatch:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()

    def _run(self) -> None:
        logged: tuple[int, str] | None = None  # the call said in the log
        ended_at: float | None = None  # when the run's end was seen
        while not self._stop.wait(WATCH_PERIOD_S):
            if ended_at is None and self.owner.over():
                ended_at = time.monotonic()
            call = self.times.in_call()
            if call is None or call["for_s"] < NOTE_AFTER_S:
                continue
            longest_s = max(HUNG_AFTER_END_S, 2.0 * self.times.max_s)  # a slow controller's step may return yet
            if ended_at is not None and time.monotonic() - ended_at >= HUNG_AFTER_END_S and call["for_s"] >= longest_s:
                self.owner.leave_hung(call)
                return
            self.stats_file.note(call)
            if call["for_s"] >= LOG_AFTER_S and logged != (call["tick"], call["call"]):
                logged = (call["tick"], call["call"])
                self.owner.complain(
                    f"{self.owner.who()} has been in its {call['call']} of tick {call['tick']} for "
                    f"{call['for_s']:.1f} s; this robot answers nothing until it returns"
                )
