"""How a run's summary tells its ending: a world that died is the run's
failure, by name and how it ended; a robot's second answer to a tick is a
rejection with its reason, counted in ``rejected`` and on the console."""

from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any

from formation_swarm.launch.console import print_result
from formation_swarm.launch.launcher import RunResult
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")


def _summary(parts: dict[str, Any], events: list[dict[str, Any]], reason: str, code: int = 1) -> dict[str, Any]:
    return summary_mod.build(
        run_id="r1",
        sc=FIG11,
        mode="lockstep",
        parts=parts,
        processes={},
        events=events,
        recording=None,
        exit_code=code,
        end_reason=reason,
        ended_at_s=None,
        interrupted=False,
        timed_out=False,
    )


def test_a_world_killed_during_the_run_is_the_run_s_failure() -> None:
    events = [{"event": "exited", "process": "world", "code": -9, "sim_time_s": 1.25, "log_tail": []}]
    s = _summary({}, events, summary_mod.ROLE_FAILED)
    assert s["failure"] == "the world was killed by SIGKILL after sim t=1.25 s (its last status): the run ended"
    assert s["end_reason"] == summary_mod.ROLE_FAILED
    assert re.findall(r"world|SIG\w+|t=", s["ended"]) == ["world", "SIGKILL"]  # no ended_at_s: no time said


def test_a_world_that_exited_with_an_error_before_the_run_is_the_run_s_failure() -> None:
    events = [{"event": "exited", "process": "world", "code": 1, "sim_time_s": -1.0}]
    s = _summary({}, events, summary_mod.ROLE_FAILED)
    assert re.findall(r"world|code -?\d+|SIG\w+|t=", s["failure"]) == ["world", "code 1"]  # no sim time: none yet
    assert "before the run started" in s["failure"]


def test_a_world_failure_comes_before_what_else_failed() -> None:
    """The leader's agent lost, then the world killed: both, the world first."""
    world = {"deaths": [{"robot": 1, "time_s": 2.0, "cause": "lost"}], "dead_robots": [1]}
    events = [{"event": "exited", "process": "world", "code": -15, "sim_time_s": 3.0}]
    s = _summary({"world": world}, events, summary_mod.ROLE_FAILED)
    told = [re.findall(r"world|leader|robot \d+|lost|SIG\w+|t=-?[\d.]+", part) for part in s["failure"].split("; ")]
    assert told == [["world", "SIGTERM", "t=3.00"], ["leader", "robot 1", "lost", "t=2.00"]]


def test_a_process_that_failed_before_tick_0_is_the_failure_when_the_world_did_not() -> None:
    """The run could not start without agent-2 (the world was stopped, not failed)."""
    events = [{"event": "exited", "process": "agent-2", "code": 2, "sim_time_s": -1.0}]
    s = _summary({}, events, summary_mod.ROLE_FAILED)
    assert re.findall(r"world|agent-\d+|code -?\d+", s["failure"]) == ["agent-2", "code 2"]  # the world not blamed


def test_a_run_that_ended_well_has_no_failure_from_its_processes() -> None:
    world = {"end_reason": summary_mod.DURATION_REACHED, "ended_at_s": 53.0}
    s = _summary({"world": world}, [], summary_mod.DURATION_REACHED, code=0)
    assert s["failure"] is None


def test_rejections_count_a_robot_s_second_answer_to_a_tick_with_its_reason() -> None:
    parts = {
        "world": {"rejected": {"replayed or reordered": 2}, "duplicate_agents": {"3": 4, "2": 1}},
        "agent-2": {"rejected": {"sender mismatch": 1}},
        "agent-3": {"rejected": {}},
    }
    assert summary_mod.rejections(parts) == {
        "world": {"replayed or reordered": 2, summary_mod.DUPLICATE_ANSWER: 5},
        "agent-2": {"sender mismatch": 1},
    }
    assert summary_mod.rejections({"world": {"duplicate_agents": {"3": 2}}}) == {"world": {"duplicate answer": 2}}
    # What a receiver of stats distrusts: counts that are no counts, tables that are no tables.
    assert summary_mod.rejections({"world": {"duplicate_agents": {"3": "x", "4": True}}, "logger": []}) == {}


def test_the_console_s_rejected_line_counts_the_duplicate_answers(tmp_path: Path) -> None:
    world = {
        "ticks": 100,
        "sim_time_s": 5.0,
        "end_reason": summary_mod.DURATION_REACHED,
        "ended_at_s": 5.0,
        "lockstep_misses": 0,
        "rejected": {"replayed or reordered": 1},
        "duplicate_agents": {"3": 7},
    }
    s = _summary({"world": world}, [], summary_mod.DURATION_REACHED, code=0)
    assert (s["rejected"], s["rejected_total"]) == ({"world": {"duplicate answer": 7, "replayed or reordered": 1}}, 8)
    out = io.StringIO()
    print_result(RunResult(tmp_path, s, 0), out)
    (line,) = [x for x in out.getvalue().splitlines() if "lockstep misses" in x]
    assert line.endswith("rejected 8 (duplicate answer 7, replayed or reordered 1)"), line


def test_the_run_folder_lines_point_to_the_wire_recording_when_there_is_one(tmp_path: Path) -> None:
    s = _summary({"world": {"ticks": 10, "ended_at_s": 0.5}}, [], summary_mod.DURATION_REACHED, code=0)
    said: list[list[str]] = []
    for _ in range(2):
        out = io.StringIO()
        print_result(RunResult(tmp_path, s, 0), out)
        said.append([x.split()[1] for x in out.getvalue().splitlines() if x.startswith("  messages:")])
        (tmp_path / "wire.mcap").write_bytes(b"")
    assert said == [[], [str(tmp_path / "wire.mcap")]]
