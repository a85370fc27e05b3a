"""Robots of an engine's run driven from outside (Engine.observe, step(actions),
inputs, wheels, formation_errors): the law's own wheels given back are the
run, other wheels move the robot as told, the errors are the metrics', and
bad actions are refused before the tick runs."""

from __future__ import annotations

import math

import pytest

from formation_swarm import Engine

SHORT = {"run.duration_s": 2.0}  # fig11's first 40 ticks, in its triangle


def test_giving_each_follower_its_own_laws_wheels_is_the_run() -> None:
    plain = Engine("fig11_obstacles", overrides={"run.duration_s": 10.0}).run()
    engine = Engine("fig11_obstacles", overrides={"run.duration_s": 10.0})
    ticks = 0
    while engine.observe():
        wheels = engine.wheels
        assert set(wheels) == {1, 2, 3}
        engine.step({2: wheels[2], 3: wheels[3]})
        ticks += 1
    driven = engine.run()
    assert ticks == driven.ticks == 200
    assert driven.trajectory_digest == plain.trajectory_digest
    assert driven.followers == plain.followers


def test_a_driven_follower_runs_the_wheels_it_is_given() -> None:
    engine = Engine("fig11_obstacles", overrides=SHORT)
    start = engine.poses[2]
    while engine.observe():
        engine.step({2: (0.5, 0.5)})
    end = engine.poses[2]
    # 40 ticks straight ahead at 0.5 m/s (no wheel noise here): 1 m along its heading.
    assert end.theta_rad == pytest.approx(start.theta_rad, abs=1e-12)
    assert math.hypot(end.x_m - start.x_m, end.y_m - start.y_m) == pytest.approx(1.0, abs=1e-9)
    res = engine.run()
    assert res.world["clamped_commands"] == 0
    assert res.followers["2"]["rms_m"] > 1.0  # the leader went on at up to 1.5 m/s: robot 2 fell behind


def test_the_formation_errors_are_those_the_metrics_record() -> None:
    engine = Engine("fig11_obstacles", overrides=SHORT)
    errors = [engine.formation_errors()]  # tick 0
    while engine.step():
        errors.append(engine.formation_errors())
    res = engine.run()
    # The metrics record ticks 0-39; the last errors are of the state after tick 39's step.
    for rid in (2, 3):
        seen = [e[rid] for e in errors[:40]]
        assert math.sqrt(sum(e * e for e in seen) / len(seen)) == pytest.approx(res.followers[str(rid)]["rms_m"])
        assert max(seen) == pytest.approx(res.followers[str(rid)]["max_m"])
    assert errors[0][2] < 1e-12  # every robot starts on its slot


def test_inputs_are_each_followers_of_the_tick_observed() -> None:
    engine = Engine("fig11_obstacles", overrides=SHORT)
    assert (engine.inputs, engine.wheels) == ({}, {})
    assert engine.observe() is True
    assert engine.observe() is True  # the tick is open: nothing more runs
    assert engine.tick == 0
    inputs = engine.inputs
    assert set(inputs) == {2, 3}
    two = inputs[2]
    assert (two.slot.reference, tuple(two.slot.offset), two.ticks, two.dt_s) == (1, (-1.5, -1.5), 1, 0.05)
    # Robot 2's slot is 1.5 m left of and behind the leader; its marker is 0.1 m behind the leader's centre.
    assert two.reading is not None
    assert two.reading.rho_m == pytest.approx(math.hypot(1.5, 1.4), abs=0.3)  # camera noise: sigma 0.05 m
    engine.step()
    assert engine.wheels == {}
    assert engine.inputs.keys() == {2, 3}  # still the tick observed last


def test_a_follower_without_an_agent_has_no_input_and_takes_no_action() -> None:
    engine = Engine("fig11_obstacles", overrides=SHORT, faults="restart agent-3@1s after=0.5s")
    missing = []
    while engine.observe():
        if 3 not in engine.inputs:
            missing.append(engine.tick)
            assert 3 not in engine.wheels
        engine.step({3: (1.0, 1.0)})  # taken only while it answers
    assert missing == list(range(20, 30))


@pytest.mark.parametrize(
    ("actions", "why"),
    [
        ({9: (0.0, 0.0)}, r"actions: 9 is not a robot of this run; robots are \[1, 2, 3\]"),
        ({True: (0.0, 0.0)}, "actions: True is not a robot"),
        ({2: (0.0,)}, r"actions\[2\] must be two wheel speeds \(left_mps, right_mps\), got \(0.0,\)"),
        ({2: "ab"}, r"actions\[2\] must be two wheel speeds"),
        ({2: (math.nan, 0.0)}, r"actions\[2\] left_mps must be a finite number within \+-3 m/s .*got nan"),
        ({2: (0.0, 3.5)}, r"actions\[2\] right_mps must be a finite number within \+-3 m/s .*got 3.5"),
        ([(2, (0.0, 0.0))], "actions must map robot ids to"),
    ],
)
def test_bad_actions_are_refused_before_the_tick_runs(actions: object, why: str) -> None:
    engine = Engine("fig11_obstacles", overrides=SHORT)
    with pytest.raises(ValueError, match=why):
        engine.step(actions)  # type: ignore[arg-type]
    assert engine.tick == 0
    engine.step({2: (3.0, -3.0)})  # at the limit: taken
    assert engine.tick == 1


def test_the_end_reason_is_none_while_the_run_goes_on() -> None:
    engine = Engine("fig11_obstacles", overrides={"run.duration_s": 0.5})
    reasons = []
    while engine.step():
        reasons.append(engine.end_reason)
    assert (reasons, engine.end_reason) == ([None] * 9, "duration_reached")
    assert engine.observe() is False
