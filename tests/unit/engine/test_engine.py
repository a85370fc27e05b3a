"""The engine (formation_swarm.Engine): a run stepped tick by tick in this
process, the same run again after a reset, the faults it refuses, and the
summary it gives, as ``swarm run`` would (no process is started here)."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from formation_swarm import Engine, EngineResult
from formation_swarm.common.faults import Fault
from formation_swarm.nodes.agent.setup import role_for

SHORT = {"run.duration_s": 5.0}  # fig7's turning run, its first 100 ticks
RESTART = "restart agent-3@20s after=1s"


def test_a_reset_runs_the_same_run_again_and_a_seed_another() -> None:
    engine = Engine("fig7_turn_vn_dynamic", overrides=SHORT)
    first = engine.run()
    engine.reset()
    again = engine.run()
    assert (again.trajectory_digest, again.ticks) == (first.trajectory_digest, 100)
    assert again.summary["followers"] == first.summary["followers"]
    engine.reset(seed=2)
    other = engine.run()
    assert (engine.seed, other.summary["seed"]) == (2, 2)
    assert other.trajectory_digest != first.trajectory_digest
    engine.reset(seed=1)
    assert engine.run().trajectory_digest == first.trajectory_digest
    assert Engine("fig7_turn_vn_dynamic", seed=1, overrides=SHORT).run().trajectory_digest == first.trajectory_digest


def test_a_step_is_one_tick_and_a_step_after_the_end_does_nothing() -> None:
    engine = Engine("fig7_turn_vn_dynamic", overrides=SHORT)
    dt = engine.scenario.dt_s
    start = engine.poses
    assert (engine.tick, engine.time_s, engine.running) == (0, 0.0, True)
    assert engine.step() is True
    assert engine.tick == 1
    assert engine.time_s == pytest.approx(dt)
    moved = engine.poses
    # The leader (robot 1) drives up its first leg (+y) at no more than its 1.5 m/s.
    assert moved[1].x_m == pytest.approx(start[1].x_m)
    assert 0.0 < moved[1].y_m - start[1].y_m <= 1.5 * dt + 1e-12
    said = [True]  # each step's answer: the run goes on, until the step that ends it
    while said[-1]:
        said.append(engine.step())
    assert (len(said), said.count(False), engine.tick, engine.running) == (100, 1, 100, False)
    assert engine.step() is False
    assert engine.tick == 100
    res = engine.run()  # nothing left to step: the result of the run as stepped
    assert (res.ticks, res.end_reason, res.exit_code) == (100, "duration_reached", 0)


def test_the_result_is_what_swarm_run_reports() -> None:
    res = Engine("fig11_obstacles", seed=1, faults=["drop obs:2@3s for=4s p=0.3", RESTART]).run()
    assert isinstance(res, EngineResult)
    assert (res.exit_code, res.end_reason, res.ticks, res.notes) == (0, "leader_finished", 1061, ())
    s = res.summary
    assert (s["mode"], s["seed"], s["lockstep_misses"], s["collisions"]) == ("lockstep", 1, 0, 0)
    assert set(res.followers) == {"2", "3"}
    assert res.followers["3"]["until_stopped"]["rms_m"] < res.followers["3"]["rms_m"]  # stopped 1 s, then caught up
    assert [(e["event"], e["process"], e["tick"], e["sim_time_s"]) for e in res.events] == [
        ("killed", "agent-3", 400, 20.0),
        ("started", "agent-3.2", 420, 21.0),
    ]
    drop, restart = s["faults"]
    assert drop["counts"]["dropped"] == s["links"]["obs:0>2"]["dropped"] > 0
    assert [e["event"] for e in restart["events"]] == ["killed", "started", "readmitted", "rejoined"]
    assert s["partial_links"] == []  # no agent here dies with counts unwritten
    assert set(s["parts"]) == {"world", "agent-1", "agent-2", "agent-3", "agent-3.2"}
    assert s["robot_digests"] == res.world["robot_digests"]
    json.dumps(s, allow_nan=False)  # JSON as summary.json is: NaN written as None


@pytest.mark.parametrize(
    ("fault", "why"),
    [
        (
            "kill agent-3@20s",
            "a kill is a SIGKILL of a process and the engine runs every robot in this one; "
            "swarm run does it (restart and freeze run here)",
        ),
        ("freeze logger@5s for=2s", "the engine has no logger process (it records nothing); swarm run has one"),
    ],
)
def test_a_fault_that_needs_processes_is_refused_in_one_line(fault: str, why: str) -> None:
    with pytest.raises(ValueError, match="^fault ") as given:
        Engine("fig11_obstacles", faults=[fault])
    assert str(given.value) == f"fault '{Fault.parse(fault)}': {why}"
    with pytest.raises(ValueError, match="a kill is a SIGKILL"):  # the scenario's own [[faults]] too
        Engine("fig11_obstacles", overrides={"faults": [{"kind": "kill", "target": "agent-2", "at_s": 3}]})


def test_bad_input_is_refused_before_anything_runs() -> None:
    with pytest.raises(ValueError, match="seed 2 and run.seed 3 in the overrides: give it once"):
        Engine("fig11_obstacles", seed=2, overrides={"run.seed": 3})
    with pytest.raises(ValueError, match="did you mean 'fig11_obstacles'"):
        Engine("fig11_obstacle")
    with pytest.raises(ValueError, match="no robot 9 in this run"):
        Engine("fig11_obstacles", faults="blackout 9@3s")
    with pytest.raises(ValueError, match="overrides must map scenario keys to values, got list"):
        Engine("fig11_obstacles", overrides=[("run.seed", 1)])  # type: ignore[arg-type]


def test_a_failing_controller_stops_its_robot_and_fails_the_run() -> None:
    law = {"controller.law": "tests.helpers.controllers:Paper", "controller.params.fail_at_step": 20, **SHORT}
    res = Engine("fig7_turn_vn_dynamic", overrides=law).run()
    assert res.exit_code == 1
    (failure,) = res.summary["controller_failures"]
    assert (failure["robot"], failure["tick"]) == (2, 20)
    assert res.summary["failure"].startswith("a controller failed, its robot stopped")
    (note,) = res.notes  # what the agent's log would have: the error and its traceback
    assert note.startswith("agent-2: controller tests.helpers.controllers:Paper failed at tick 20")
    assert "Traceback" in note


def test_importing_the_engine_loads_neither_zenoh_nor_rerun_nor_the_launcher() -> None:
    probe = (
        "import json, sys\nfrom formation_swarm import Engine\nEngine\n"
        "print(json.dumps([m for m in ('zenoh', 'rerun', 'formation_swarm.launch.launcher') if m in sys.modules]))"
    )
    res = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout) == []


def test_poses_are_the_worlds_and_finite() -> None:
    engine = Engine("fig11_obstacles", overrides={"run.duration_s": 1.0})
    engine.run()
    final = engine.run().world["final_poses"]
    assert {str(rid): list(p) for rid, p in engine.poses.items()} == final
    assert all(math.isfinite(v) for p in engine.poses.values() for v in p)


def test_every_role_starts_in_the_formation_leader_formation_names() -> None:
    # fig11 starts in its first formation, the triangle; told to fly its line, no role ever holds the triangle.
    engine = Engine("fig11_obstacles", overrides={"leader.formation": "line", "run.duration_s": 2.0})
    sc = engine.scenario
    line = sc.code_of("line")
    assert line != 0
    roles = {rid: role_for(sc, rid, sc.seed) for rid in sc.robots}
    assert {rid: role.code for rid, role in roles.items()} == dict.fromkeys(sc.robots, line)
    slots = sc.formation_by_code(line).slots
    assert {rid: (role.slot.reference, *role.slot.offset) for rid, role in roles.items() if rid in slots} == {
        rid: (slot.reference, *map(float, slot.offset)) for rid, slot in slots.items()
    }
    s = engine.run().summary
    assert s["formation_events"] == []  # not the triangle at tick 0, then the line at tick 1
    agents = {name: part for name, part in s["parts"].items() if name.startswith("agent-")}
    assert {name: (part["formation"], part["formation_changes"]) for name, part in agents.items()} == {
        f"agent-{rid}": ("line", []) for rid in sc.robots
    }
