"""A script that starts a Launch without ``if __name__ == "__main__":`` gets
one line naming the fix, before any process or folder is made, instead of
multiprocessing's traceback about the "bootstrapping phase" from a child
that imported the script again (tests/unit/launch/test_mainguard.py has
the rules)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from formation_swarm.launch import mainguard
from tests.helpers import processes

SCRIPT = """\
from formation_swarm.launch.launcher import Launch

with Launch("fig11_obstacles", out={out!r}, logger=False) as launch:
    launch.wait(timeout_s=120)
"""


@pytest.mark.slow  # a Python process that imports the launcher
def test_an_unguarded_script_is_refused_before_anything_starts(tmp_path: Path) -> None:
    script = tmp_path / "my_run.py"
    script.write_text(SCRIPT.format(out=str(tmp_path / "run")))
    done = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last == f"formation_swarm.launch.mainguard.MainGuardError: {mainguard.message(str(script))}"
    assert "bootstrapping" not in done.stderr
    assert done.stdout == ""
    assert not (tmp_path / "run").exists()
    deadline = time.monotonic() + 10
    while (left := processes(lambda cmd: str(tmp_path) in cmd)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not left, left
