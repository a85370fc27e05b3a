"""Suite-wide guard: no process of ours may outlive the test session."""

from __future__ import annotations

import pytest

from tests.helpers import processes


@pytest.fixture(scope="session", autouse=True)
def _no_process_left_behind(tmp_path_factory: pytest.TempPathFactory) -> object:
    # Every process the suite starts names a file under its base temp folder
    # (a run's scenario, a viewer's output): runs of other sessions or users,
    # and processes started before, do not count.
    base = str(tmp_path_factory.getbasetemp())
    before = {pid for pid, _ in processes(lambda cmd: base in cmd)}
    yield
    left = [(pid, cmd) for pid, cmd in processes(lambda cmd: base in cmd) if pid not in before]
    assert not left, f"processes left behind by the suite: {left}"
