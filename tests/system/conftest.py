"""Fixtures shared by the system tests."""

from __future__ import annotations

from typing import Any

import pytest

from formation_swarm.launch.launcher import Launch


@pytest.fixture(scope="session")
def clean_run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The summary of a clean lockstep fig11 run (no logger), once per test process:
    the ticks, times and digests an attack or a leaked login must leave alone."""
    run_dir = tmp_path_factory.mktemp("clean") / "run"
    with Launch("fig11_obstacles", out=run_dir, logger=False, progress=lambda _l: None) as run:
        res = run.wait(timeout_s=240)
    assert res.exit_code == 0
    return res.summary


@pytest.fixture(scope="session")
def clean_digest(clean_run: dict[str, Any]) -> str:
    """The trajectory digest of that clean run."""
    return str(clean_run["trajectory_digest"])
