"""check_controller (formation_swarm.engine.check): docs/controllers.md's
complete controller and the built-in laws pass; each fault of
tests/unit/engine/check_controllers.py is one line naming its check; a law
that cannot be built is a ValueError; the caller's random states are left
as they were."""

from __future__ import annotations

import random
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from formation_swarm import ControllerSetup, FollowerInput, FollowerOutput
from formation_swarm.engine.check import RECORD_TICKS, check_controller, recorded, run_checks
from tests.helpers import ROOT
from tests.unit.engine.check_controllers import LAW

PAGE = (ROOT / "docs" / "controllers.md").read_text()
COMPLETE = re.findall(r"^```python\n(.*?)^```$", PAGE, re.M | re.S)[0]
CHECKS = 12  # without reset and close: build, stream, 4 on every answer, 4 changed streams, determinism, global random


@pytest.fixture
def my_controller(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    (tmp_path / "my_controller.py").write_text(COMPLETE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "my_controller:Proportional"
    sys.modules.pop("my_controller", None)


def test_the_pages_complete_controller_passes_every_check(my_controller: str) -> None:
    report = run_checks(my_controller)
    assert (report.law, report.problems, len(report.checks)) == (my_controller, (), CHECKS)
    assert check_controller(my_controller, {"speed_gain": 2.0}, robot=3) == []


@pytest.mark.parametrize("law", ["fuzzy", "lpsi"])
def test_the_built_in_laws_pass(law: str) -> None:
    report = run_checks(law, ticks=200)  # 10 s of fig11: the full stream takes a second
    assert (report.problems, len(report.checks)) == ((), CHECKS)


def test_the_recorded_stream_is_what_robot_2_got_in_fig11() -> None:
    stream = recorded("fig11_obstacles", 0, 2, RECORD_TICKS)
    assert len(stream) == RECORD_TICKS
    assert [i for i, inp in enumerate(stream) if inp.slot_moved] == [393, 609]  # into the line and back
    assert {inp.slot.reference for inp in stream} == {1}
    assert sum(inp.reading is None for inp in stream) == 0
    assert {(inp.ticks, inp.dt_s) for inp in stream} == {(1, 0.05)}


NAN = "finite: left_mps is nan at input 0 of the recorded stream: the robot would stop for the rest of the run"
RAISES = "stream: step() raised RuntimeError: failing on purpose at input 4 of the recorded stream"
BLIND = "no reading: step() raised AttributeError: 'NoneType' object has no attribute 'rho_m' at input 0 of"
FED = 5 * RECORD_TICKS + RECORD_TICKS // 3  # the inputs of the six runs: five whole streams, one 3 ticks a step


@pytest.mark.parametrize(
    ("name", "said"),
    [
        ("Nan", f"{NAN}; {FED - 1} more alike"),
        ("Raises", f"{RAISES}; the same in determinism, no reading, several ticks, slot change, new reference"),
        ("Pair", "output: step() returned tuple (0.0, 0.0), not a FollowerOutput at input 0 of the recorded stream"),
        ("Blind", f"{BLIND} the stream with no reading at first and for a while mid-stream"),
        ("OneTick", "several ticks: step() raised ValueError: ticks=3 at input 0 of the stream 3 ticks a step"),
    ],
)
def test_a_faulty_controller_is_one_line_naming_its_check(name: str, said: str) -> None:
    problems = check_controller(f"{LAW}:{name}")
    assert len(problems) == 1
    assert problems[0].startswith(said)


@pytest.mark.parametrize(("name", "state"), [("PyRandom", "random"), ("NpRandom", "numpy.random")])
def test_a_draw_from_a_global_random_state_is_refused_twice(name: str, state: str) -> None:
    random.seed(7)
    np.random.seed(7)
    before = random.getstate(), np.random.get_state()
    problems = check_controller(f"{LAW}:{name}")
    assert [p.split(": ")[0] for p in problems] == ["determinism", "global random"]
    assert problems[0].startswith("determinism: two instances built alike answered input 0 of the recorded stream")
    assert re.findall(r"from ([\w.]+)'s global state", problems[1]) == [state]  # the state it drew from, named
    assert random.getstate() == before[0]  # the caller's states as they were
    assert np.array_equal(np.random.get_state()[1], before[1][1])


def test_reset_and_close_are_checked_where_the_class_has_them() -> None:
    report = run_checks(f"{LAW}:Counts")
    assert len(report.checks) == CHECKS + 2
    assert [p.split(": ")[0] for p in report.problems] == ["close", "reset"]
    assert report.problems[0].startswith("close: close() raised OSError: no such device at the end of the recorded")
    # Its first answer after reset() is its 351st step's, 0.351 m/s; a fresh one's is 0.001 m/s.
    assert re.findall(r"after reset\(\)|input \d+|fresh", report.problems[1]) == ["after reset()", "input 0", "fresh"]


def test_a_class_made_in_a_function_is_checked_with_its_params() -> None:
    class Mine:
        PARAMS = {"speed_mps": 0.5}

        def __init__(self, setup: ControllerSetup) -> None:
            self.speed = setup.law_params["speed_mps"]

        def step(self, inp: FollowerInput) -> FollowerOutput:
            return FollowerOutput(left_mps=self.speed, right_mps=self.speed)

    assert check_controller(Mine, {"speed_mps": 2}) == []
    assert check_controller(Mine, {"speed_mps": 4.0}, robot=3)[0].startswith(
        "wheel limit: left_mps = 4 m/s, beyond robot.max_wheel_mps = 3 at input 0 of the recorded stream"
    )
    with pytest.raises(ValueError, match=r"unknown key followers\.2\.params\.speed; did you mean 'speed_mps'"):
        check_controller(Mine, {"speed": 1.0})


@pytest.mark.parametrize(
    ("law", "params", "robot", "said"),
    [
        (f"{LAW}:Stil", None, None, "has no class 'Stil'; did you mean 'Still'?"),
        ("no_such_module:Law", None, None, "cannot import 'no_such_module'"),
        (f"{LAW}:Still", {"speed_mps": "fast"}, None, "followers.2.params.speed_mps must be a number"),
        (f"{LAW}:Still", None, 1, "robot 1 is not a follower of fig11-obstacles; its followers are [2, 3]"),
    ],
)
def test_a_law_that_cannot_be_built_is_a_value_error(
    law: str, params: dict[str, object] | None, robot: int | None, said: str
) -> None:
    with pytest.raises(ValueError, match=re.escape(said)):
        check_controller(law, params, robot=robot)
