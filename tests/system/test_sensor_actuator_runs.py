"""Sensor and actuator faults in real lockstep runs (world, agents, one
process each): a camera blackout and its recovery, and the reproducibility of
runs with wheel noise and outliers."""

from __future__ import annotations

import io
import math
from collections.abc import Callable

from formation_swarm.launch.console import print_result
from formation_swarm.launch.launcher import Launch, RunResult
from formation_swarm.spec import scenario as sm
from formation_swarm.world.kinematics import Pose, from_body_frame
from tests.helpers import SCENARIOS, run_together
from tests.helpers.replica import replay

FIG11 = "fig11_obstacles"  # three robots in a triangle: 1 leads 2, 2 leads 3


def _r3_error_at_end(res: RunResult) -> float:
    sc = sm.load(FIG11)
    poses = {int(k): Pose(*v) for k, v in res.summary["parts"]["world"]["final_poses"].items()}
    slot = sc.formations["triangle"].slots[3]
    tx, ty = from_body_frame(poses[slot.reference], *slot.offset)
    return math.hypot(tx - poses[3].x_m, ty - poses[3].y_m)


def test_a_blackout_of_robot_3_opens_its_error_and_it_recovers(swarm_run: Callable[..., RunResult]) -> None:
    short = {"run.duration_s": 18}  # the obstacles come into the leader's range at 19.6 s: triangle throughout
    clean = swarm_run(FIG11, mode="lockstep", logger=False, overrides=short)
    dark = swarm_run(FIG11, mode="lockstep", logger=False, overrides=short, faults=["blackout 3@5s for=3s"])
    for res in (clean, dark):
        assert res.exit_code == 0
        assert res.summary["lockstep_misses"] == 0
    r3, r3_clean = dark.summary["followers"]["3"], clean.summary["followers"]["3"]
    # Blind for 3 s, R3 stops after controller.lost_after_s (1 s) while its reference drives on at ~1.5 m/s.
    # Measured: max 0.87 m without the blackout, 3.18 m with it (at 8.0 s, its end); below 0.5 m again by 14 s.
    assert r3["max_m"] > r3_clean["max_m"] + 1.5
    # Ten seconds after the blackout it is back in its slot, as close as without the fault (0.16 m both).
    assert _r3_error_at_end(dark) < _r3_error_at_end(clean) + 0.1
    assert _r3_error_at_end(dark) < 0.5
    assert dark.summary["followers"]["2"] == clean.summary["followers"]["2"]  # R2 saw everything as before
    assert dark.summary["sensor_faults"] == {"blackout 3@5s for=3s": {"3": {"ticks": 60, "blacked_out": 120}}}
    console = io.StringIO()
    print_result(dark, console)
    assert dark.summary["faults"][0]["counts"] == {"R3 ticks": 60, "R3 blacked_out": 120}
    (back,) = dark.summary["faults"][0]["recoveries"]  # from the 1 s windows after the end, at 8 s
    assert back["watched"] == [3]
    # Measured: 8 s, its 1 s mean below 0.5 m from the window 15-16 s (the error itself by 14 s, swinging).
    assert 0.0 < back["first_below_after_s"] <= 10.0
    said = console.getvalue()
    assert "  fault: blackout 3@5s for=3s: R3 below 0.5 m (1 s mean) within " in said
    assert "; R3: on for 60 ticks, 120 readings blacked out\n" in said


def test_lockstep_runs_with_wheel_noise_and_outliers_are_reproducible(swarm_launch: Callable[..., Launch]) -> None:
    faults = ["wheel_noise *@0s sigma_mps=0.1", "outliers 2,3@0s p=0.05"]
    short = {"run.duration_s": 20}
    kwargs = {"mode": "lockstep", "logger": False, "overrides": short, "faults": faults}
    a, b = (r.summary for r in run_together(swarm_launch, (FIG11, kwargs), (FIG11, kwargs)))
    assert a["lockstep_misses"] == b["lockstep_misses"] == 0
    assert a["trajectory_digest"] == b["trajectory_digest"]
    # and the same run replayed in one process (the engine, the brains, the links) draws the same noise
    assert (
        replay(SCENARIOS / "fig11_obstacles.toml", 1, {**short, "faults": faults})["trajectory_digest"]
        == (a["trajectory_digest"])
    )
    assert a["sensor_faults"] == b["sensor_faults"]
    assert a["actuator_faults"] == b["actuator_faults"]
    replaced = a["sensor_faults"]["outliers 2,3@0s p=0.05"]
    assert 0 < replaced["2"]["replaced"] < 0.1 * 2 * 400
    assert replaced["3"]["ticks"] == 400
    assert a["actuator_faults"]["wheel_noise *@0s sigma_mps=0.1"]["1"]["moving_ticks"] > 300
