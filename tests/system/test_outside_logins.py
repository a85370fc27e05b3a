"""An outside agent's login, and a second session on a robot's login.

The launcher deletes the outside agent's login file once its token is there,
as every other process deletes its own. A second agent on a copy of it has
its answers refused and is named at the end. The world, the run's router,
hears each session close (what it needs to see a token kept by a second
session: tests/system/test_outside_deaths.py). An outside agent that never
connects is named in the run's ``ended`` line, with the deadline that ran out.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh

from formation_swarm.launch.launcher import Launch, free_port
from formation_swarm.nodes.world.sessions import LoginWatch
from formation_swarm.protocol import trust
from formation_swarm.protocol.session import make_config
from tests.helpers import foreign_follower as foreign

FIG11 = "fig11_obstacles"
FOREIGN = Path(foreign.__file__)


@contextmanager
def foreign_agent(flags: list[str], folder: Path) -> Iterator[subprocess.Popen[bytes]]:
    """The foreign follower of docs/protocol, flying with these flags; killed and reaped at the end."""
    with open(folder / "foreign.log", "wb") as log:
        proc = subprocess.Popen(
            [sys.executable, str(FOREIGN), *flags, "--stats", str(folder / "foreign.json")],
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        )
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=30)


def hold_token(session: zenoh.Session, key: str) -> zenoh.LivelinessToken:
    """A token held by ``session``, once the router has it: a liveliness query
    sent after it on the same link is answered after the router took it."""
    token = session.liveliness().declare_token(key)
    assert list(session.liveliness().get(key, timeout=10.0)), f"no answer for {key}"
    return token


def wait_for(predicate: Any, timeout_s: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


# -- the world's watch, on a router in this process ----------------------------------------


@pytest.mark.slow
def test_the_world_hears_each_session_close_and_records_a_kept_token(tmp_path: Path) -> None:
    run = f"watch-{uuid.uuid4().hex[:8]}"
    files = trust.write_run_secrets(tmp_path / "secrets", run, (1, 2, 3), leader_id=1)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    said: list[str] = []
    closed = threading.Event()
    with zenoh.open(make_config("router", listen=[endpoint], settings=trust.read_settings(files["router"]))) as router:
        watch = LoginWatch(router, lambda: {"tick": 7, "time_s": 0.35, "wall_s": 1.0}, said.append)
        watch.listen()
        watch.wake = closed.set
        login = trust.read_settings(files["agent-2"])
        with (
            zenoh.open(make_config("client", [endpoint], settings=login)),
            zenoh.open(make_config("client", [endpoint], settings=login)),
        ):
            assert not closed.wait(timeout=0.5)  # sessions that open are not told
        assert closed.wait(timeout=10.0)
        assert wait_for(lambda: watch.closed == 2)
    assert watch.kept([]) == []
    assert watch.kept([2]) == [2]
    assert watch.records == [{"robot": 2, "login": "agent-2", "tick": 7, "time_s": 0.35, "wall_s": 1.0}]
    assert len(said) == 1
    assert "login agent-2" in said[0]


# -- a run with an outside agent -----------------------------------------------------------


@pytest.mark.slow
def test_the_outside_agents_login_goes_once_it_is_connected_and_a_second_session_is_said(tmp_path: Path) -> None:
    """The login file, copied before the agent connected, starts a second
    agent beside the real one: its answers are refused and, at the end, the
    launcher names the login that answered from two sessions."""
    lines: list[str] = []
    launch = Launch(FIG11, external=[3], out=tmp_path / "run", logger=False, progress=lines.append)
    agent = launch.prepare()[3]
    assert agent.login is not None
    login = agent.login
    copy = trust.write_settings(tmp_path / "copy.json", trust.read_settings(login))  # taken while it is there
    beside = tmp_path / "beside"
    beside.mkdir()
    try:
        launch.start()
        with foreign_agent(agent.flags(), tmp_path) as proc:
            assert launch.wait_until(lambda: not login.exists(), timeout_s=90), lines
            assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=90), lines
            flags = [*agent.flags()[:-1], str(copy), "--fly-beside"]
            with foreign_agent(flags, beside) as second:
                res = launch.wait(timeout_s=240)
                assert second.wait(timeout=30) == 0, (beside / "foreign.log").read_text()
            assert proc.wait(timeout=30) == 0, (tmp_path / "foreign.log").read_text()
    finally:
        launch.stop()
    s = res.summary
    theirs = json.loads((tmp_path / "foreign.json").read_text())
    assert res.exit_code == 0, s["events"]
    assert s["deaths"] == []
    connected = [e for e in s["events"] if e["event"] == "outside agent connected"]
    assert [e["robot"] for e in connected] == [3]
    assert connected[0]["wall_s"] < 60.0
    refused = s["parts"]["world"]["duplicate_agents"]["3"]
    used = [e for e in s["events"] if e["event"] == "robot login used twice"]
    assert [(e["robot"], e["login"], e["answers_refused"]) for e in used] == [(3, "agent-3", refused)]
    assert refused > 0
    warned = [line for line in lines if line.startswith("[swarm] warning: robot 3's login agent-3 answered from two")]
    assert len(warned) == 1, lines
    assert f"({refused} answers refused)" in warned[0]
    assert sum("robot 3's outside agent connected: its login file is deleted" in line for line in lines) == 1
    assert theirs["answered"] == s["ticks"] == 1061  # the real agent answered every tick
    assert not (launch.run_dir / "secrets").exists()


@pytest.mark.slow
def test_an_outside_agent_that_never_connects_is_named_in_the_ended_line(tmp_path: Path) -> None:
    """Before, the agents that left when the world gave up were blamed: "a
    process failed (agent-1 exited with code 3)"."""
    out = tmp_path / "run"
    argv = [sys.executable, "-m", "formation_swarm.cli", "run", FIG11, "--external", "3", "--no-logger"]
    done = subprocess.run(
        [*argv, "--peers-timeout", "3", "--out", str(out)], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 1, done.stdout + done.stderr
    s = json.loads((out / "summary.json").read_text())
    said = (
        "the outside agent of robot 3 (swarm run --external) never connected: the world gave up waiting after 3 s "
        "(--peers-timeout); it waited for: no agent for robot 3"
    )
    assert (s["end_reason"], s["ended"], s["exit_code"]) == ("peers_timeout", said, 1)
    assert s["parts"]["world"]["waited_for"] == {"robots": [3], "missing": "no agent for robot 3", "timeout_s": 3.0}
    ended = [line for line in done.stdout.splitlines() if line.startswith("  ended: ")]
    assert ended == [f"  ended: {said}"], done.stdout
