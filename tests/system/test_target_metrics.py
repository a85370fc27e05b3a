"""The target metrics tell the truth: at a formation switch the true target is
that of the formation flown at that tick; a follower that never saw its
reference has no metrics; the summary says why the run ended."""

from __future__ import annotations

import io
import math
from collections.abc import Callable

import numpy as np
import pytest

from formation_swarm.launch.launcher import RunResult
from formation_swarm.report.data import read_recording
from formation_swarm.spec import scenario as scenario_mod


def test_true_target_at_a_switch_tick_is_the_new_formations(swarm_run: Callable[..., RunResult]) -> None:
    # fig11_obstacles switches to "line" at 19.6 s (leader) and 19.65 s (followers).
    res = swarm_run("fig11_obstacles", overrides={"run.duration_s": 21.0})
    s = res.summary
    assert s["end_reason"] == "duration_reached"
    switches = {e["robot"]: e["tick"] for e in s["formation_events"] if e["formation"] == "line"}
    assert switches == {1: 392, 2: 393, 3: 393}
    sc = scenario_mod.load(res.run_dir / "scenario.toml")
    line = sc.formations["line"]
    data = read_recording(res.recording)
    dt = sc.dt_s
    errors = s["parts"]["logger"]["target_errors"]
    for rid in (2, 3):
        k = switches[rid]
        ekf = data[f"/robots/r{rid}/error/ekf"]
        at = np.flatnonzero(np.isclose(ekf.t, k * dt))
        assert len(at) == 1
        # Measured against the old (triangle) slot it was 1.5 m (R2) and 3.4 m (R3).
        assert ekf.v[at[0]] < 0.25, (rid, ekf.v[at[0]])
        # The published true target is the line slot's: its offset away from the
        # line's reference (in the triangle: 2.1 m from R1 for both followers).
        truth, slot = data[f"/robots/r{rid}/target/true"], line.slots[rid]
        ref = data[f"/robots/r{slot.reference}/pose"]
        i, j = np.flatnonzero(np.isclose(truth.t, k * dt))[0], np.flatnonzero(np.isclose(ref.t, k * dt))[0]
        assert math.dist(truth.v[i], ref.v[j]) == pytest.approx(math.hypot(*slot.offset), abs=1e-3)
        # The logger's RMS is the RMS of the errors it recorded; the recorded
        # formation error is the world's own (same formation at every tick).
        assert errors[str(rid)]["ekf_rms_m"] == pytest.approx(math.sqrt(np.mean(ekf.v**2)), rel=1e-9)
        form = data[f"/robots/r{rid}/error/formation"]
        assert s["followers"][str(rid)]["rms_m"] == pytest.approx(math.sqrt(np.mean(form.v**2)), rel=1e-9)
        assert float(np.max(ekf.v)) < 0.6, rid  # no sample near the 1.5-4.5 m slot jump


def test_a_stranded_follower_is_reported_never_acquired(swarm_run: Callable[..., RunResult]) -> None:
    from formation_swarm.launch.console import print_result
    from formation_swarm.report.build import make_report

    # R3 starts 3 m from its reference R2, and its camera sees no farther than 2.5 m: it never sees it.
    # (A scenario whose cameras cannot see a reference from its slot is refused at load.)
    res = swarm_run("fig11_obstacles", faults=["range 3@0s m=2.5"], overrides={"run.duration_s": 3.0})
    s = res.summary
    assert s["scenario_warnings"] == []
    r2, r3 = s["followers"]["2"], s["followers"]["3"]
    assert (r2["acquired"], r2["frames"], r2["seen_ticks"]) == (True, 60, 60)
    assert r2["rms_m"] < 0.5
    assert (r3["acquired"], r3["frames"], r3["seen_ticks"]) == (False, 60, 0)
    assert r3["rms_m"] is None
    assert r3["max_m"] is None
    text = io.StringIO()
    print_result(res, text)
    out = text.getvalue()
    assert "follower R3: NEVER ACQUIRED its reference (never in its camera's view): no metrics" in out
    assert "follower R2: formation error RMS" in out
    assert "ended: the scenario's duration was reached at t=3.00 s" in out
    assert s["end_reason"] == "duration_reached"
    assert s["ended_at_s"] == 3.0
    md = (make_report(res.run_dir) / "report.md").read_text()
    assert "| R3 | never acquired its reference: no metrics |" in md


def test_why_a_run_ended_in_words() -> None:
    from formation_swarm.runtime.summary import describe_end

    assert describe_end("leader_finished", 53.05) == "the leader reached its last waypoint at t=53.05 s"
    assert describe_end("interrupted", 2.0) == "stopped by a signal (Ctrl-C, SIGINT or SIGTERM) at t=2.00 s"
    events = [
        {"event": "killed", "process": "agent-3", "sim_time_s": 1.0},
        {"event": "exited", "process": "agent-3", "code": -9, "sim_time_s": 1.0},  # the kill's doing
        {"event": "exited", "process": "world", "code": 1, "sim_time_s": 4.5},
        {"event": "exited", "process": "logger", "code": 0, "sim_time_s": 4.5},
    ]
    assert describe_end("role_failed", 4.5, events) == "a process failed at t=4.50 s (world exited with code 1)"
    assert describe_end("role_failed", None, []) == "a process failed"


def test_the_target_error_is_against_the_formation_the_follower_flew() -> None:
    """In real time a follower may fly a new formation a tick before the world
    has its command naming it: the world's truth still holds the old slot's
    target. The follower's reading of its new slot is measured against the new
    slot's true target (its telemetry says which), not metres off the old one."""
    import rerun as rr

    from formation_swarm.nodes.logger.recorder import Recorder
    from formation_swarm.nodes.logger.recording import Recording
    from formation_swarm.protocol.messages import Telemetry, Truth
    from formation_swarm.world.kinematics import Pose, from_body_frame, to_body_frame

    sc = scenario_mod.load("fig11_obstacles")
    stream = rr.RecordingStream("formation-swarm-test", recording_id="flown-target")
    stream.memory_recording()
    rec = Recording(file=stream)
    recorder = Recorder(rec, sc)
    poses = {1: Pose(0.0, 0.0, math.pi / 2), 2: Pose(-1.5, -1.5, math.pi / 2), 3: Pose(1.5, -1.5, math.pi / 2)}
    line, triangle = sc.code_of("line"), sc.code_of("triangle")
    old = sc.formations["triangle"].slots[3]
    new = sc.formations["line"].slots[3]
    world_target = from_body_frame(poses[old.reference], *old.offset)  # the truth's: still the triangle's
    flown_target = from_body_frame(poses[new.reference], *new.offset)
    assert math.dist(world_target, flown_target) > 3.0
    robots = tuple((rid, p.x_m, p.y_m, p.theta_rad, True) for rid, p in poses.items())
    recorder.add_truths([Truth(sender=0, seq=1, tick=7, time_s=0.35, robots=robots, targets=((3, *world_target),))])
    seen = to_body_frame(poses[3], *flown_target)  # a perfect reading of the line slot's target
    tel = Telemetry(
        sender=3,
        seq=1,
        tick=7,
        time_s=0.35,
        reference=new.reference,
        formation=line,
        measured=seen,
        estimate=seen,
        target_cov=(0.01, 0.0, 0.01),
        rho_m=1.5,
        alpha_rad=0.0,
        vn=1.5,
        left_mps=1.5,
        right_mps=1.5,
        steering_to=new.reference,
        changing=True,
        obs_dropped=0,
        formation_dropped=0,
        rejected=0,
    )
    recorder.add_telemetry([tel])
    recorder.send(final=True)
    errors = recorder.stats()["target_errors"]["3"]
    assert errors["ekf_rms_m"] == pytest.approx(0.0, abs=1e-9)
    assert errors["measured_rms_m"] == pytest.approx(0.0, abs=1e-9)
    # A code it does not know falls back to the world's target.
    assert (triangle, line) == (0, 1)
    unknown = Recorder(rec, sc)
    unknown.add_truths([Truth(sender=0, seq=1, tick=7, time_s=0.35, robots=robots, targets=((3, *world_target),))])
    unknown.add_telemetry(
        [
            Telemetry(
                sender=3,
                seq=1,
                tick=7,
                time_s=0.35,
                reference=new.reference,
                formation=9,
                measured=seen,
                estimate=seen,
                target_cov=None,
                rho_m=1.5,
                alpha_rad=0.0,
                vn=1.5,
                left_mps=1.5,
                right_mps=1.5,
                steering_to=new.reference,
                changing=True,
                obs_dropped=0,
                formation_dropped=0,
                rejected=0,
            )
        ]
    )
    unknown.send(final=True)
    far = math.dist(world_target, flown_target)
    assert unknown.stats()["target_errors"]["3"]["ekf_rms_m"] == pytest.approx(far, rel=1e-6)
