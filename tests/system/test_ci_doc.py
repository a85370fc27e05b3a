"""docs/ci.md's GitHub Actions workflow works: the page shows the file
examples/ci/github-actions.yml, and its `run:` steps, run here in a fresh
virtual environment with the package installed from this repository instead
of the git URL, pass a user's fixture test that flies the user's own
controller package (a copy of examples/pure_pursuit, its law found by name).

PyYAML is not a dependency: the few lines needed (the top-level `env:`, each
step's `uses:`, `with:` and `run:`) are read by `workflow()` below, which
refuses what it does not read rather than misread it.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers import ROOT, processes
from tests.helpers.tracked import copy_tracked

DOC = ROOT / "docs" / "ci.md"
EXAMPLE = ROOT / "examples" / "ci" / "github-actions.yml"
# The user's repository: a controller package (examples/pure_pursuit's files but its tests) and the page's test.
PACKAGE = ROOT / "examples" / "pure_pursuit"
PACKAGE_FILES = ("pyproject.toml", "README.md", "pure_pursuit_controller.py")


def workflow(text: str) -> tuple[dict[str, str], list[dict[str, str]]]:
    """The top-level env and the steps of a one-job workflow: each step's keys
    (``name``, ``uses``, ``run``, ``if``, and ``with.KEY`` for what its ``with:`` holds)."""
    env: dict[str, str] = {}
    steps: list[dict[str, str]] = []
    section, step_indent = "", -1
    for line in text.splitlines():
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        indent = len(line) - len(line.lstrip())
        key, _, value = line.strip().removeprefix("- ").partition(":")
        value = value.strip().strip('"')
        if value in ("|", ">", "|-", ">-"):
            raise ValueError(f"block scalars are not read here: {line!r}")
        if indent == 0:
            section = key
        elif section == "env" and indent == 2:
            env[key] = value
        elif line.strip().startswith("- ") and key in ("uses", "name", "run"):
            steps.append({key: value})
            step_indent = indent + 2
        elif steps and indent == step_indent and key != "with":
            steps[-1][key] = value
        elif steps and indent > step_indent:
            steps[-1][f"with.{key}"] = value
    return env, steps


def test_the_page_shows_the_example_file() -> None:
    blocks = re.findall(r"^```yaml\n(.*?)^```$", DOC.read_text(), re.M | re.S)
    assert blocks == [EXAMPLE.read_text()]


def test_the_workflow_sets_up_python_3_11_with_pips_cache_installs_and_runs_pytest() -> None:
    env, steps = workflow(EXAMPLE.read_text())
    assert env["FORMATION_SWARM"].startswith("formation-swarm @ git+https://")
    setup = next(s for s in steps if s.get("uses", "").startswith("actions/setup-python@"))
    assert (setup["with.python-version"], setup["with.cache"]) == ("3.11", "pip")
    # setup-python keys its cache on a file it must find in the user's repository.
    assert setup["with.cache-dependency-path"] == ".github/workflows/fixture-tests.yml"
    runs = [s["run"].split() for s in steps if "run" in s]  # word by word, quotes kept: the requirement has spaces
    assert runs == [
        ["python", "-m", "pip", "install", '"$FORMATION_SWARM"', "pytest", "."],  # "." is the user's package
        ["python", "-m", "pytest", "--basetemp=pytest-runs"],
    ]
    assert steps.index(setup) < min(i for i, s in enumerate(steps) if "run" in s)


def _pypi_reachable() -> bool:
    try:
        socket.create_connection(("pypi.org", 443), timeout=5).close()
    except OSError:
        return False
    return True


@pytest.mark.slow  # a fresh environment: pip installs the package and its dependencies (1-3 min)
def test_the_workflows_run_steps_pass_a_users_fixture_test(tmp_path: Path) -> None:
    env_vars, steps = workflow(EXAMPLE.read_text())
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    project = tmp_path / "project"
    (project / "tests").mkdir(parents=True)
    (test,) = re.findall(r"^```python\n(.*?)^```$", DOC.read_text(), re.M | re.S)
    assert '"controller.law": "pure_pursuit"' in test  # the page's test flies the user's law
    (project / "tests" / "test_formation.py").write_text(test)
    for name in PACKAGE_FILES:
        shutil.copy2(PACKAGE / name, project / name)
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME")}
    env |= env_vars
    env["FORMATION_SWARM"] = str(copy_tracked(tmp_path / "formation-swarm"))  # not the git URL
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"  # as setup-python leaves it
    # pip's --no-compile through its environment, the steps as written: byte-compiling numpy,
    # scipy, pyarrow and rerun is a third of the install; the fixture test compiles what it imports.
    env["PIP_COMPILE"] = "0"
    for step in (s for s in steps if "run" in s):
        done = subprocess.run(
            ["bash", "-eo", "pipefail", "-c", step["run"]],
            cwd=project,
            env=env,
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            timeout=1200,
        )
        out = f"{done.stdout[-4000:]}\n{done.stderr[-4000:]}"
        if done.returncode != 0 and "pip install" in step["run"] and not _pypi_reachable():
            reason = f"no network access to PyPI, and pip's cache could not satisfy the install: {out[-500:]}"
            print(reason)
            pytest.skip(reason)
        assert done.returncode == 0, f"step {step.get('name', step['run'])!r} exited {done.returncode}:\n{out}"
    assert "1 passed" in done.stdout, done.stdout
    # multiprocessing's resource tracker of the user's session leaves a moment after it.
    deadline = time.monotonic() + 30
    while (left := processes(lambda cmd: str(tmp_path) in cmd)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not left, left
