"""Suite-wide guard: no process of ours may outlive the test session."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"
OUR_MODULES = ("world.process", "agents.process", "swarm.logger", "swarm.router")


def our_processes() -> list[tuple[int, str]]:
    """Live processes running one of our roles (zombies excluded)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (entry / "stat").read_text().split(") ", 1)[1][0]
        except OSError:
            continue
        if state != "Z" and any(f"-m {m} " in cmd for m in OUR_MODULES):
            found.append((int(entry.name), cmd.strip()))
    return found


@pytest.fixture(scope="session", autouse=True)
def _no_process_left_behind(tmp_path_factory: pytest.TempPathFactory) -> object:
    # Every run of the suite lives under its base temp folder (the run's scenario
    # path is in each command line): runs of other sessions or users do not count.
    base = str(tmp_path_factory.getbasetemp())
    before = {pid for pid, _ in our_processes()}
    yield
    left = [(pid, cmd) for pid, cmd in our_processes() if pid not in before and base in cmd]
    assert not left, f"processes left behind by the suite: {left}"
