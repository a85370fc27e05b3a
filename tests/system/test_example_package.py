"""examples/pure_pursuit works as a user's own package: this project's wheel
and the example installed into a fresh virtual environment outside the
repository, where the example's tests (its controller alone, then real runs
through the ``swarm_run`` fixture and its entry point) pass."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers import processes
from tests.helpers.tracked import copy_tracked


def _pypi_reachable() -> bool:
    try:
        socket.create_connection(("pypi.org", 443), timeout=5).close()
    except OSError:
        return False
    return True


def _run(args: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        args, cwd=cwd, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=1800
    )


@pytest.mark.slow  # a wheel, a fresh environment and its dependencies (1-3 min), then three runs
def test_the_example_package_passes_its_tests_against_this_projects_wheel(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME")}
    source = copy_tracked(tmp_path / "formation-swarm")  # what a user gets: no build output of this tree
    wheels = tmp_path / "wheels"
    built = _run([sys.executable, "-m", "pip", "wheel", ".", "--no-deps", "-w", str(wheels)], source, env)
    assert built.returncode == 0, built.stdout[-2000:] + built.stderr[-2000:]
    (wheel,) = wheels.glob("formation_swarm-*.whl")
    venv = tmp_path / "venv"
    # This pip installs into the fresh environment (--python), which needs no pip of its own;
    # --no-compile: byte-compiling numpy, scipy, pyarrow and rerun is a third of the install,
    # and the example's tests compile only what they import.
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = str(venv / "bin" / "python")
    example = source / "examples" / "pure_pursuit"
    pip = [sys.executable, "-m", "pip", "--python", python, "install", "--no-compile"]
    installed = _run([*pip, str(wheel), f"{example}[test]"], tmp_path, env)
    if installed.returncode != 0 and not _pypi_reachable():
        reason = f"no network access to PyPI, and pip's cache could not satisfy the install: {installed.stderr[-500:]}"
        print(reason)
        pytest.skip(reason)
    assert installed.returncode == 0, installed.stdout[-2000:] + installed.stderr[-2000:]
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    tested = _run(
        [python, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--basetemp", str(tmp_path / "t")], example, env
    )
    assert tested.returncode == 0, tested.stdout[-4000:] + tested.stderr[-2000:]
    assert "3 passed" in tested.stdout, tested.stdout
    # multiprocessing's resource tracker of that session leaves a moment after it.
    deadline = time.monotonic() + 30
    while (left := processes(lambda cmd: str(tmp_path) in cmd)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not left, left
