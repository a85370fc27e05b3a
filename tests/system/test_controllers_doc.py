"""docs/controllers.md stays true: its complete controller flies fig11_obstacles
from the command line with the errors the page gives, its unit test and its
fixture example pass as a user's test files, its code imports only the
package's public names, and its tables name what the code has."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import formation_swarm
from formation_swarm.agents.controller import (
    COUNTED_STOPS,
    LOST,
    STATS_VALUES,
    WIRE_VALUES,
    ControllerSetup,
    FollowerInput,
    FollowerOutput,
    TargetEstimate,
)
from formation_swarm.agents.laws import ENTRY_POINT_GROUP
from formation_swarm.protocol.messages import EXTRA_NAME, MAX_EXTRAS
from tests.helpers import ROOT

DOC = ROOT / "docs" / "controllers.md"
TEXT = DOC.read_text()
SWARM = Path(sys.executable).parent / "swarm"
COMMAND = [str(SWARM)] if SWARM.exists() else [sys.executable, "-m", "formation_swarm.cli"]


def blocks(fence: str) -> list[str]:
    return re.findall(rf"^```{fence}\n(.*?)^```$", TEXT, re.M | re.S)


def test_the_complete_controller_flies_fig11_as_the_page_says(tmp_path: Path) -> None:
    (tmp_path / "my_controller.py").write_text(blocks("python")[0])
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    law = "controller.law=my_controller:Proportional"
    proc = subprocess.run(
        [*COMMAND, "run", "fig11_obstacles", "--no-logger", "--set", law, "--out", "run"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    said = re.search(r"within ([\d.]+) m \(R2\) and ([\d.]+) m \(R3\)", TEXT)
    assert said is not None
    for rid, value in zip(("2", "3"), said.groups(), strict=True):
        assert s["followers"][rid]["rms_m"] == pytest.approx(float(value), abs=0.05)
    assert (s["collisions"], s["controller_failures"]) == (0, [])


def test_the_pages_misspelt_class_is_refused_as_shown(tmp_path: Path) -> None:
    (tmp_path / "my_controller.py").write_text(blocks("python")[0])
    shown = next(b for b in blocks("console") if "Proportionl" in b).splitlines()
    command, said = shown[0].removeprefix("$ swarm ").split(), shown[1]
    proc = subprocess.run(
        [*COMMAND, *command],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(tmp_path)},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    head, tail = said.split("...")
    assert proc.stderr.startswith(head), proc.stderr
    assert proc.stderr.rstrip().endswith(tail), proc.stderr
    assert list(tmp_path.iterdir()) == [tmp_path / "my_controller.py"]


def test_the_tables_name_the_interface() -> None:
    for cls in (ControllerSetup, FollowerInput, FollowerOutput, TargetEstimate):
        for name in cls.__dataclass_fields__:
            assert f"`{name}`" in TEXT, (cls.__name__, name)
    for name in (*WIRE_VALUES, *STATS_VALUES):
        assert f"`{name}`" in TEXT, name
    for stop in (*COUNTED_STOPS, LOST):
        assert f'`"{stop}"`' in TEXT, stop
    assert f'"{ENTRY_POINT_GROUP}"' in TEXT
    assert f"At most {MAX_EXTRAS} such names" in TEXT
    assert EXTRA_NAME.pattern == "[A-Za-z][A-Za-z0-9_]{0,31}"  # "1 to 32 characters, a letter then ..."


def test_the_pages_code_imports_only_the_public_names() -> None:
    code = "\n".join(blocks("python"))
    imported = {
        n.strip() for names in re.findall(r"^from formation_swarm import (.+)$", code, re.M) for n in names.split(",")
    }
    assert imported == {
        "ControllerSetup",
        "Engine",
        "FollowerInput",
        "FollowerOutput",
        "FollowerParams",
        "MarkerReading",
        "Point",
        "Slot",
    }
    assert imported <= set(formation_swarm.__all__)
    assert "formation_swarm." not in code


def test_the_pages_unit_test_passes_as_a_users_test(tmp_path: Path) -> None:
    (tmp_path / "my_controller.py").write_text(blocks("python")[0])
    (tmp_path / "test_alone.py").write_text(blocks("python")[2])
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_alone.py"],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(tmp_path)},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout


@pytest.mark.slow
def test_the_fixture_example_passes_as_a_users_test(tmp_path: Path) -> None:
    (tmp_path / "my_controller.py").write_text(blocks("python")[0])
    (tmp_path / "test_mine.py").write_text(blocks("python")[1])
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_mine.py"],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(tmp_path)},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout
