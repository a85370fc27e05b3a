"""Robots K by K in a process: the command lines grouped, each robot's own
line found again (a restart's), and the launcher's calls to one robot."""

from __future__ import annotations

import os
import signal
from pathlib import Path

from formation_swarm.launch import sharing
from formation_swarm.launch.processes import Processes
from formation_swarm.nodes.agent.shared import CALL_SIGNAL, Calls, ControlFile, Robots, split_argv
from formation_swarm.runtime.children import Child

PY = ["python", "-m"]


def _agent(rid: int) -> list[str]:
    return [*PY, sharing.AGENT_MODULE, "--id", str(rid), "--stats", f"s/agent-{rid}.json", "--connect", "tcp/x:1"]


def _lines(n: int) -> dict[str, list[str]]:
    return {"world": [*PY, "w"], "logger": [*PY, "l"], **{f"agent-{r}": _agent(r) for r in range(1, n + 1)}}


def test_k_of_1_leaves_a_process_per_robot(tmp_path: Path) -> None:
    assert sharing.group(_lines(3), 1, tmp_path / "control") == _lines(3)
    assert not (tmp_path / "control").exists()


def test_eleven_robots_ten_by_ten_make_two_processes_each_robots_line_kept_whole(tmp_path: Path) -> None:
    out = sharing.group(_lines(11), 10, tmp_path / "control")
    assert list(out) == ["world", "logger", "agents-1-10", "agents-11"]
    assert out["agents-1-10"][:5] == [*PY, sharing.MODULE, "--control", str(tmp_path / "control/agents-1-10.calls")]
    robots = sharing.robots_in(out["agents-1-10"])
    assert list(robots) == [f"agent-{r}" for r in range(1, 11)]
    assert robots["agent-7"] == _agent(7)  # what a restart of robot 7 starts, alone
    own, groups = split_argv(out["agents-11"][3:])
    assert (own, groups) == (["--control", str(tmp_path / "control/agents-11.calls")], [_agent(11)[3:]])
    assert sharing.robots_in(_agent(3)) == {}


def test_a_robots_fault_is_a_call_to_its_process_read_back_in_order(tmp_path: Path) -> None:
    argv = sharing.group(_lines(4), 4, tmp_path / "control")["agents-1-4"]
    assert not (tmp_path / "control").exists()  # made at the first call: a run with none has no control/
    procs = Processes(journal=None)  # type: ignore[arg-type]
    procs.children["agents-1-4"] = Child("agents-1-4", argv, tmp_path / "log")
    procs.current["agents-1-4"] = "agents-1-4"
    procs.shared["agents-1-4"] = sharing.Control(sharing.control_path(argv))
    procs.current.update(dict.fromkeys(sharing.robots_in(argv), "agents-1-4"))
    procs.sharer.update(dict.fromkeys(sharing.robots_in(argv), "agents-1-4"))
    assert procs.act("agent-3", "freeze") == "agents-1-4"
    assert procs.frozen == {"agent-3"}
    procs.thaw("agent-3")
    assert procs.act("agent-2", "kill") == "agents-1-4"
    assert procs.first_argv("agent-2") == _agent(2)
    control = ControlFile(sharing.control_path(argv))
    assert control.read() == ["1 freeze 3", "2 thaw 3", "3 kill 2"]
    assert control.read() == []


def test_the_shared_process_takes_only_well_formed_calls_in_order(tmp_path: Path) -> None:
    path = tmp_path / "calls"
    path.write_bytes(b"1 freeze 3\n1 freeze 3\n2 explode 3\n3 kill 9\nx" + b"y" * 100 + b"\n4 thaw")
    robots = Robots("agents 1,2,3")
    control = ControlFile(path)
    lines = control.read()
    assert lines[-1].startswith("x")  # a whole line, read as given; the last, unfinished, waits
    for line in lines:
        robots.execute(line)
    # The first is taken (no robot 3 here yet: rejected after its seq is taken), then: a replay,
    # an unknown action, a robot not of this process, a line too long.
    assert (robots.last_seq, robots.rejected) == (3, 5)
    with path.open("ab") as f:
        f.write(b" 3\n")
    assert control.read() == ["4 thaw 3"]


class _Taken(Robots):
    """Robots that keep the calls they are given: (seq, action, robot)."""

    def __init__(self) -> None:
        super().__init__("agents 1,2")
        self.calls: list[tuple[str, ...]] = []

    def execute(self, line: str) -> None:
        self.calls.append(tuple(line.split()))


def test_each_call_wakes_its_process_which_reads_it_on_the_signal(tmp_path: Path) -> None:
    assert sharing.CALL_SIGNAL == CALL_SIGNAL  # the launcher's and the process's, without an import between
    woken: list[int] = []
    control = sharing.Control(tmp_path / "calls", wake=lambda: woken.append(control.seq))
    taken = _Taken()
    calls = Calls(ControlFile(control.path), taken)
    old = signal.signal(CALL_SIGNAL, calls.read)
    try:
        control.call("freeze", "agent-2")
        os.kill(os.getpid(), CALL_SIGNAL)  # the handler runs in this (main) thread before kill returns here
        assert taken.calls == [("1", "freeze", "2")]
        control.call("thaw", "agent-2")
        calls.busy = True  # a signal that lands during a read: that read reads again
        calls.read()
        assert len(taken.calls) == 1
        calls.busy = False
        calls.read()
        assert (taken.calls, woken) == ([("1", "freeze", "2"), ("2", "thaw", "2")], [1, 2])
    finally:
        signal.signal(CALL_SIGNAL, old)
