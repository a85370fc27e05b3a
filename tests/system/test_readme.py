"""README.md stays short, and every command it gives to run works as written.

Fences: a ```sh block is run, command by command, as a reader would type it;
a ```console block is shown and not run (it needs a second machine, a
viewer, a run that lasts, or a file of the reader's own).

The commands run in a fresh copy of the repository's tracked files, with
this interpreter's environment (the worktree's .venv) first on PATH, so that
`swarm`, `make`, `rerun` resolve as after `make run`. A `make TARGET`
command runs as `make -n TARGET`: it proves the target exists and prints
what it would do, without creating a second .venv, running the suite inside
the suite, or the two hours of `make results`. Every other command runs
for real and must exit 0.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import ROOT
from tests.helpers.tracked import copy_tracked

README = ROOT / "README.md"
MAX_BYTES = 12 * 1024
RUNNABLE = "sh"


def commands(text: str, fence: str = RUNNABLE) -> list[str]:
    """The commands of every ```fence block, in order: continued lines
    (ending in a backslash) joined, blank lines and whole-line comments left out."""
    found: list[str] = []
    for block in re.findall(rf"^```{fence}\n(.*?)^```$", text, re.M | re.S):
        for command in re.sub(r"\s*\\\n\s*", " ", block).splitlines():
            if command.strip() and not command.lstrip().startswith("#"):
                found.append(command.strip())
    return found


def as_run(command: str) -> str:
    """What the test runs for a README command: ``make X`` dry (``make -n X``)."""
    return re.sub(r"^make\b", "make -n", command)


def test_the_readme_fits_in_12_kb() -> None:
    size = len(README.read_bytes())
    assert size <= MAX_BYTES, f"README.md is {size} bytes, more than {MAX_BYTES}: move the details to docs/"


def test_the_commands_are_found_in_their_fences() -> None:
    text = "```sh\nmake run  # x\n\n# a comment\nswarm run a \\\n    --seed 1\n```\n```console\nswarm host\n```\n"
    # A comment stays on its command; a continued line is joined: compared word by word.
    assert [c.split() for c in commands(text)] == [["make", "run", "#", "x"], ["swarm", "run", "a", "--seed", "1"]]
    assert commands(text, "console") == ["swarm host"]
    assert as_run("make results  # long").split() == ["make", "-n", "results", "#", "long"]
    swarm = "swarm run fig11_obstacles"
    assert as_run(swarm) == swarm  # only make is run dry
    readme = commands(README.read_text())
    assert [c.partition("#")[0].split() for c in readme[:2]] == [["make", "run"], ["make", "test"]]
    assert all(" # " in c for c in readme[:2])  # each with its comment
    assert any(c.startswith("swarm run ") for c in readme), readme


@pytest.mark.slow  # three lockstep runs and a report: 15-25 s here
def test_every_runnable_readme_command_exits_0(tmp_path: Path) -> None:
    repo = copy_tracked(tmp_path / "repo")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.pop("MAKEFLAGS", None)
    for command in commands(README.read_text()):
        done = subprocess.run(
            ["bash", "-c", as_run(command)],
            cwd=repo,
            env=env,
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert done.returncode == 0, (
            f"README command {command!r} exited {done.returncode}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
        )


def test_what_is_here_has_a_line_for_every_folder() -> None:
    """The table lists each top-level folder, each subpackage of swarm/ and
    each folder of tests/, as they are in the tree."""
    text = README.read_text().split("## What is here", 1)[1]
    listed = set(re.findall(r"^\| `([\w/]+)/` \|", text, re.M))
    tree = {p.name for p in ROOT.iterdir() if p.is_dir() and not p.name.startswith(".") and _tracked(p)}
    for parent in ("swarm", "tests"):
        tree |= {f"{parent}/{p.name}" for p in (ROOT / parent).iterdir() if (p / "__init__.py").is_file()}
    assert tree <= listed, f"folders missing from README's 'What is here': {sorted(tree - listed)}"


def _tracked(folder: Path) -> bool:
    out = subprocess.run(["git", "ls-files", "--", folder.name], cwd=ROOT, capture_output=True, text=True, check=True)
    return bool(out.stdout.strip())
