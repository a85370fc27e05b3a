"""A host's answer to a start request sent twice: the launcher's retry of a
start whose first reply came late gets the same success, not a refusal."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from formation_swarm.common.version import __version__
from formation_swarm.nodes.host import runs as hosting
from formation_swarm.protocol.hostmsg import HostReply, HostRequest


class _FakeChild:
    """An agent that runs until told otherwise, started without a process."""

    next_pid = 1000

    def __init__(self, name: str, argv: list[str], log_path: Path) -> None:
        self.name, self.argv, self.log_path = name, argv, log_path
        self.pid: int | None = None
        self.code: int | None = None

    def start(self) -> None:
        _FakeChild.next_pid += 1
        self.pid = _FakeChild.next_pid

    def poll(self) -> int | None:
        return self.code


class _Session:
    """What Host.open_run asks of a Zenoh session: a liveliness subscriber."""

    def liveliness(self) -> _Session:
        return self

    def declare_subscriber(self, *_args: Any, **_kwargs: Any) -> Any:
        return None


@pytest.fixture
def host(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> hosting.Host:
    monkeypatch.setattr(hosting, "Child", _FakeChild)
    return hosting.Host(_Session(), "a", robots=None, connect=[], settings={}, workdir=tmp_path)  # type: ignore[arg-type]


def _start(password: str = "p" * 24, scenario: str = "x = 1") -> bytes:
    req = HostRequest(
        "start", __version__, run="r1", process="agent-2", scenario=scenario, user="agent-2", password=password
    )
    return req.to_bytes()


def test_the_same_start_twice_gets_the_same_success_and_one_agent(host: hosting.Host) -> None:
    first = host.handle(_start())
    again = host.handle(_start())  # a retry: its first reply was late
    assert first.ok, first.error
    assert again.ok, again.error
    assert again.pid == first.pid
    assert len(host.runs["r1"].children) == 1


def test_another_start_of_a_running_agent_is_refused(host: hosting.Host) -> None:
    first = host.handle(_start())
    other: HostReply = host.handle(_start(scenario="x = 2"))
    assert not other.ok
    assert other.error.startswith("agent-2 of run r1 ")  # the process and its run
    assert f"(pid {first.pid})" in other.error  # the one that runs


def test_the_same_start_after_the_agent_ended_starts_a_fresh_one(host: hosting.Host) -> None:
    first = host.handle(_start())
    host.runs["r1"].children["agent-2"].code = 0  # type: ignore[attr-defined]
    again = host.handle(_start())
    assert again.ok
    assert again.pid != first.pid
