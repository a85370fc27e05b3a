"""A host writes its run's scenario at every start; an agent of that run
started before reads it as it starts, and must read it whole (seen: an agent
that read it half written exited with code 2)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from formation_swarm.common.version import __version__
from formation_swarm.nodes.host import runs as hosting
from formation_swarm.protocol.hostmsg import HostRequest


class _Child:
    """An agent started without a process; it reads nothing itself."""

    def __init__(self, name: str, argv: list[str], log_path: Path) -> None:
        self.name, self.argv, self.log_path, self.pid = name, argv, log_path, 1000

    def start(self) -> None:
        pass

    def poll(self) -> int | None:
        return None


class _Session:
    def liveliness(self) -> _Session:
        return self

    def declare_subscriber(self, *_args: Any, **_kwargs: Any) -> Any:
        return None


def _start(process: str, scenario: str) -> bytes:
    return HostRequest(
        "start", __version__, run="r1", process=process, scenario=scenario, user=process, password="p" * 24
    ).to_bytes()


def test_a_start_replaces_the_scenario_whole_under_an_agent_reading_it(tmp_path: Path, monkeypatch: Any) -> None:
    monkeypatch.setattr(hosting, "Child", _Child)
    host = hosting.Host(_Session(), "b", robots=None, connect=[], settings={}, workdir=tmp_path)  # type: ignore[arg-type]
    assert host.handle(_start("agent-2", "# first\n[run]\n")).ok
    path = tmp_path / "r1" / "scenario.toml"
    with path.open() as reading:  # agent-2, as it starts
        assert host.handle(_start("agent-3", "# second, longer\n[run]\n")).ok
        assert reading.read() == "# first\n[run]\n"  # before, the file it read was cut short and written again
    assert path.read_text().splitlines() == ["# second, longer", "[run]"]  # the second whole
    assert sorted(p.name for p in path.parent.iterdir()) == ["logs", "scenario.toml", "secrets", "stats"]


def test_write_whole_leaves_no_part_behind(tmp_path: Path) -> None:
    path = tmp_path / "scenario.toml"
    hosting.write_whole(path, "a = 1\n")
    hosting.write_whole(path, "a = 2\n")
    assert path.read_text() == "a = 2\n"
    assert [p.name for p in tmp_path.iterdir()] == ["scenario.toml"]
