"""The package as another project sees it: built as a wheel, installed with pip
into a fresh virtualenv outside the repository, used from a project that has
its own ``agents`` package."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from tests.helpers import ROOT

pytestmark = pytest.mark.slow

USER_TEST = """
import agents


def test_the_local_agents_package_is_the_one_imported():
    assert agents.OWNER == "the user's project"


def test_a_shipped_scenario_by_name_with_a_kill_given_as_a_string(swarm_run):
    res = swarm_run("fig11_obstacles", kills=["agent-3@20"], logger=False, timeout_s=240)
    print("SUMMARY", res.summary["exit_code"], res.summary["ticks"], res.summary["deaths"])
    assert res.summary["ticks"] == 1061
    assert [d["robot"] for d in res.summary["deaths"]] == [3]
    assert [e["process"] for e in res.summary["events"] if e["event"] == "killed"] == ["agent-3"]
"""


def _run(argv: list[str], cwd: Path, timeout_s: float) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout_s, check=False)


@pytest.fixture(scope="session")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    res = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(ROOT)], out, 300)
    assert res.returncode == 0, res.stderr
    (whl,) = out.glob("formation_swarm-*.whl")
    return whl


def test_the_wheel_installs_one_top_level_package(wheel: Path) -> None:
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        top = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
        top_level = [n for n in names if n.endswith(".dist-info/top_level.txt")]
        declared = z.read(top_level[0]).decode().split() if top_level else []
    assert top == {"formation_swarm"}
    assert declared in ([], ["formation_swarm"])
    assert "formation_swarm/scenarios/fig11_obstacles.toml" in names
    assert "formation_swarm/py.typed" in names
    # Every module of the source, subpackages too (pyproject.toml lists the packages by name).
    source = {f"formation_swarm/{p.relative_to(ROOT / 'swarm').as_posix()}" for p in (ROOT / "swarm").rglob("*.py")}
    assert source - set(names) == set()
    assert "formation_swarm/cli/__main__.py" in names  # python -m formation_swarm.cli


def test_a_project_with_its_own_agents_package_uses_the_fixture(wheel: Path, tmp_path: Path) -> None:
    venv = tmp_path / "venv"
    # This pip installs into the fresh virtualenv (--python): no copy of pip is installed there
    # first; --no-compile: byte-compiling all of numpy, scipy, matplotlib, pyarrow and rerun is a
    # third of the install, and the user's run compiles only what it imports.
    assert _run([sys.executable, "-m", "venv", "--without-pip", str(venv)], tmp_path, 120).returncode == 0
    py = str(venv / "bin" / "python")
    pip = [sys.executable, "-m", "pip", "--python", py]
    res = _run([*pip, "install", "-q", "--no-compile", str(wheel), "pytest"], tmp_path, 600)
    assert res.returncode == 0, res.stderr
    assert "Traceback" not in res.stderr

    project = tmp_path / "project"
    (project / "agents").mkdir(parents=True)
    (project / "agents" / "__init__.py").write_text('OWNER = "the user\'s project"\n')
    (project / "test_user.py").write_text(USER_TEST)
    res = _run([py, "-m", "pytest", "-q", "-s", "-p", "no:cacheprovider", "test_user.py"], project, 400)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert "2 passed" in res.stdout
    # the installed copy ran, not this repository's folders
    res = _run([py, "-c", "import formation_swarm; print(formation_swarm.__file__)"], project, 60)
    assert str(venv) in res.stdout, res.stdout
