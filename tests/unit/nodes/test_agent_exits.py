"""Every way an agent ends before its run starts leaves its reason in its
log, one line: its command line refused, its scenario unreadable (seen: one
read half written by its host), its id not a robot, another's login, a
router that never answered; and a forked agent whose launcher died as it
started (runtime.spawner)."""

from __future__ import annotations

import json
import os
import re
import signal
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from formation_swarm.nodes.agent import main as agent_main
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime import spawner
from tests.helpers import SCENARIOS

FIG11 = SCENARIOS / "fig11_obstacles.toml"
CLOSED = "tcp/127.0.0.1:1"  # nothing listens there


@pytest.fixture(autouse=True)
def _own_stop_handlers() -> Iterator[None]:
    """main() installs its stop handlers: put the test process's back."""
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    for sig, handler in before.items():
        signal.signal(sig, handler)


def _ends(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, list[str]]:
    """main()'s exit code (argparse's SystemExit too) and the lines it wrote (its log)."""
    try:
        code = agent_main.main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, [line for line in (out + err).splitlines() if line.strip()]


def _argv(*extra: str, scenario: Path = FIG11) -> list[str]:
    return ["--id", "2", "--scenario", str(scenario), "--run", "r1", "--connect", CLOSED, *extra]


def test_a_refused_command_line_says_which_flag(capsys: pytest.CaptureFixture[str]) -> None:
    code, lines = _ends(capsys, [*_argv(), "--peers-timeout", "-1"])
    assert code == process_mod.EXIT_USAGE
    (line,) = lines
    assert line.startswith("swarm agent: ")
    assert re.findall(r"--[\w-]+|'-?\d+'", line) == ["--peers-timeout", "'-1'", "--help"]  # the flag, its value


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("", "missing key run.robots"),
        ("[run]\nrobots = [", "not valid TOML"),  # a file read as it was being written
    ],
)
def test_a_scenario_read_half_written_says_why(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, text: str, why: str
) -> None:
    scenario = tmp_path / "scenario.toml"
    scenario.write_text(text)
    code, lines = _ends(capsys, _argv(scenario=scenario))
    assert code == process_mod.EXIT_USAGE
    assert len(lines) == 1
    assert lines[0].startswith(f"agent 2: {scenario}: {why}"), lines


def test_an_id_that_is_no_robot_of_the_scenario_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    code, lines = _ends(capsys, ["--id", "9", *_argv()[2:]])
    assert code == process_mod.EXIT_USAGE
    assert [re.findall(r"\d+", line) for line in lines] == [["9", "9", "1", "2", "3"]]  # the id, then the robots
    assert "not a robot" in lines[0]


def test_another_agent_s_login_says_whose_it_is(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    login = tmp_path / "agent-3.json"
    login.write_text(json.dumps({"transport/auth/usrpwd": {"user": "agent-3", "password": "p" * 24}}))
    login.chmod(0o600)
    code, lines = _ends(capsys, _argv("--auth", str(login)))
    assert code == process_mod.EXIT_USAGE
    (line,) = lines
    whose = line.removeprefix(f"agent 2: --auth {login}: ")  # else the path's agent-3.json is found too
    assert re.findall(r"agent-\d+(?:\.json)?", whose) == ["agent-3", "agent-2", "agent-2.json"]


def test_no_router_by_the_deadline_says_where_it_looked(capsys: pytest.CaptureFixture[str]) -> None:
    code, lines = _ends(capsys, _argv("--peers-timeout", "0.3"))
    assert code == process_mod.EXIT_NO_PEERS
    assert len(lines) == 1
    assert lines[0].startswith(f"agent 2: gave up after 0.3 s: no router answered at {CLOSED}; "), lines


def test_a_forked_agent_whose_launcher_died_as_it_started_says_so(tmp_path: Path) -> None:
    """The fork server gone before the agent could ask to die with it (its
    parent is then init): the agent leaves at once, 143, with a line in its log."""
    log = tmp_path / "agent-2.log"
    exit_path = tmp_path / "agent-2.log.exit"
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child: runs spawner._child as the fork server's child would
        try:
            sys.stdout, sys.stderr = sys.__stdout__, sys.__stderr__  # pytest's capture: fds the child closes
            os.getppid = lambda: 1  # type: ignore[assignment]
            spawner._child(spawner.FORKED_ROLES[0], [], str(log), {}, str(exit_path))
        finally:
            os._exit(99)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 128 + signal.SIGTERM
    assert [line.partition(": ")[0] for line in log.read_text().splitlines()] == ["agent"]  # one line
    assert "launcher died" in log.read_text()
