"""Fixtures shared by the system tests."""

from __future__ import annotations

import pytest

from formation_swarm.launch.launcher import Launch


@pytest.fixture(scope="session")
def clean_digest(tmp_path_factory: pytest.TempPathFactory) -> str:
    """The trajectory digest of a clean lockstep fig11 run: what an attack must leave alone."""
    run_dir = tmp_path_factory.mktemp("clean") / "run"
    with Launch("fig11_obstacles", out=run_dir, logger=False, progress=lambda _l: None) as run:
        res = run.wait(timeout_s=240)
    assert res.exit_code == 0
    return str(res.summary["trajectory_digest"])
