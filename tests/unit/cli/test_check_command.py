"""``swarm check-controller``, in this process: exit 0 with the count of
checks, 1 with each problem a line, 2 with one line for a law, parameter or
command line that cannot be built."""

from __future__ import annotations

import re
import shlex
import sys
from pathlib import Path

import pytest

from formation_swarm import cli
from tests.helpers import ROOT
from tests.unit.engine.check_controllers import LAW

PAGE = (ROOT / "docs" / "controllers.md").read_text()


def check(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[str], list[str]]:
    try:
        code = cli.main(["check-controller", *argv])
    except SystemExit as exc:  # argparse's own errors
        code = int(exc.code or 0)
    out = capsys.readouterr()
    return code, out.out.splitlines(), out.err.splitlines()


def test_a_controller_that_passes_says_how_many_checks(capsys: pytest.CaptureFixture[str]) -> None:
    law = f"{LAW}:Still"
    code, out, err = check(capsys, law, "--set", "speed_mps=1", "--robot", "3")
    assert (code, err, [re.findall(r"^(\S+) passes (\d+)", line) for line in out]) == (0, [], [[(law, "12")]])


def test_a_controller_with_problems_prints_each_and_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = check(capsys, f"{LAW}:Still", "--set", "speed_mps=3.5")
    assert (code, err, len(out)) == (1, [], 2)
    for line, wheel in zip(out, ("left_mps", "right_mps"), strict=True):
        assert line.startswith(f"wheel limit: {wheel} = 3.5 m/s, beyond robot.max_wheel_mps = 3 at input 0 of")


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        ([f"{LAW}:Stil"], "has no class 'Stil'; did you mean 'Still'?"),
        ([f"{LAW}:Still", "--set", "speed=1"], "unknown key followers.2.params.speed; did you mean 'speed_mps'?"),
        ([f"{LAW}:Still", "--set", "speed_mps"], "--set takes NAME=VALUE"),
        ([f"{LAW}:Still", "--robot", "1"], "robot 1 is not a follower of fig11-obstacles"),
        ([f"{LAW}:Still", "--scenario", "no_such_scenario"], "no_such_scenario"),
        ([f"{LAW}:Still", "--robot", "two"], "argument --robot: must be an integer >= 0, got 'two'"),
    ],
)
def test_what_cannot_be_built_is_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str], argv: list[str], said: str
) -> None:
    code, out, err = check(capsys, *argv)
    assert (code, out, len(err)) == (2, [], 1)
    assert err[0].startswith("swarm check-controller: ")
    assert said in err[0]


def test_the_pages_example_says_what_the_command_prints(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "my_controller.py").write_text(re.findall(r"^```python\n(.*?)^```$", PAGE, re.M | re.S)[0])
    monkeypatch.syspath_prepend(str(tmp_path))
    block = next(b for b in re.findall(r"^```console\n(.*?)^```$", PAGE, re.M | re.S) if "check-controller" in b)
    command, said = block.splitlines()
    argv = shlex.split(command.removeprefix("$ PYTHONPATH=. swarm "))
    try:
        assert check(capsys, *argv[1:]) == (0, [said], [])
    finally:
        sys.modules.pop("my_controller", None)
