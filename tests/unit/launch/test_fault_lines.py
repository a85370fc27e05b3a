"""The run's live fault lines come in tick order: a process fault's call,
handled at once, after the window faults' starts and ends before its tick
that the world's status had not yet reported."""

from __future__ import annotations

import re
from types import SimpleNamespace
from typing import Any

from formation_swarm.launch.faults import FaultExecutor
from formation_swarm.launch.processes import Processes
from formation_swarm.protocol.messages import FaultCall
from formation_swarm.spec import scenario as scenario_mod


class _Journal:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def say(self, line: str) -> None:
        self.lines.append(line)

    def add(self, *_args: Any, **_kwargs: Any) -> None:
        pass

    def wall_s(self) -> float:
        return 0.0


def test_window_faults_before_a_process_fault_s_tick_are_said_first_in_tick_order() -> None:
    faults = ["blackout 3@5s for=2s", "drop obs:2@1s for=3s p=0.3", "kill agent-2@8s"]
    sc = scenario_mod.load("fig11_obstacles", None, faults)
    child = SimpleNamespace(pid=1, signal=lambda _sig: None)
    journal = _Journal()
    procs = Processes(journal)  # type: ignore[arg-type]
    procs.children["agent-2"], procs.current["agent-2"] = child, "agent-2"  # type: ignore[assignment]
    executor = FaultExecutor(sc, procs, journal, restart=lambda name: name)  # type: ignore[arg-type]
    executor.say_windows(SimpleNamespace(last=SimpleNamespace(tick=30)))  # type: ignore[arg-type]
    kill = next(i for i, f in enumerate(sc.faults) if f.kind == "kill")
    call = FaultCall(sender=0, seq=1, tick=160, time_s=8.0, action="kill", process="agent-2", index=kill)
    executor.put(call.to_bytes())
    executor.execute_calls()
    executor.say_windows(SimpleNamespace(last=SimpleNamespace(tick=150)))  # the status, late: nothing new
    said = [re.match(r"\[swarm\] (.+?) (?:from|at) tick (\d+)", line) for line in journal.lines]
    assert [(m.group(1), int(m.group(2))) for m in said if m] == [
        ("fault on", 20),
        ("fault off", 80),
        ("fault on", 100),
        ("fault off", 140),
        ("killed agent-2", 160),
    ]
    assert len(said) == 5
