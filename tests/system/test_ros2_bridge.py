"""swarm run --ros2: the run seen and robot 3 driven through rmw_zenoh's keys,
by a client written from rmw_zenoh's design (tests.system.rosclient: rosbags'
CDR over plain Zenoh; no import of formation_swarm.ros2) with the pursuit of
examples/ros2_follower."""

from __future__ import annotations

import importlib.util
import math
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from formation_swarm import load_run
from formation_swarm.launch.launcher import Launch, RunResult
from formation_swarm.launch.ros2 import write_login
from formation_swarm.spec import scenario as scenario_mod
from tests.system.rosclient import Follower, RosNode

pytestmark = pytest.mark.slow

SC = scenario_mod.load("fig11_obstacles")
PURSUIT = Path(__file__).parents[2] / "examples" / "ros2_follower" / "pursuit.py"


def _pursuit() -> Any:
    spec = importlib.util.spec_from_file_location("ros2_pursuit", PURSUIT)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def law(poses: dict[int, tuple[float, ...]], code: int) -> tuple[float, float]:
    """Robot 3 to its slot in the formation /formation names, by the example's pursuit."""
    p = _pursuit()
    slot = SC.formation_by_code(code).slots[3]
    ref = poses.get(slot.reference)
    if ref is None:
        return 0.0, 0.0
    held = p.Slot(back_m=-slot.offset.y_m, right_m=slot.offset.x_m)
    return p.pursue(p.Pose(*poses[3][:3]), p.Pose(*ref[:3]), (ref[3], ref[4]), held)


def fly(
    tmp_path: Path, mode: str, duration_s: float | None = None, before: list[tuple[float, bytes]] | None = None
) -> tuple[RunResult, Follower, list[str], list[str]]:
    """One run of fig11_obstacles with robot 3 left to ROS: its result, the
    follower, the ROS graph it saw, the console."""
    run_id = f"ros2-{mode}-{uuid.uuid4().hex[:8]}"
    lines: list[str] = []
    overrides: dict[str, Any] = {"ros2.bridge": True}
    if duration_s is not None:
        overrides["run.duration_s"] = duration_s
    launch = Launch(
        "fig11_obstacles",
        mode=mode,
        overrides=overrides,
        external=[3],
        out=tmp_path / run_id,
        run_id=run_id,
        progress=lines.append,
        peers_timeout_s=30.0,
    )
    with launch:
        login = write_login(launch.login("ros2") or {}, tmp_path / f"{run_id}.json")  # as --ros2-login does
        node = RosNode(launch.endpoint, login)
        try:
            follower = Follower(node, 3, SC.robots, law)
            follower.before = list(before or [])
            deadline, graph = time.monotonic() + 20.0, []
            while time.monotonic() < deadline and not _seen(graph, node.zid):
                graph = node.graph()
            result = launch.wait(timeout_s=240.0)
        finally:
            node.close()
    follower.close()
    return result, follower, graph, lines


def _seen(graph: list[str], own_zid: str) -> bool:
    """The bridge's publishers of /robot2/odom and /tf, by their tokens (another session's)."""
    theirs = [k.split("/") for k in graph if k.split("/")[2] != own_zid]
    topics = {(p[5], p[9]) for p in theirs if len(p) > 9}
    return {("MP", "%robot2%odom"), ("MP", "%tf")} <= topics


def test_lockstep_seen_and_driven_from_ros(tmp_path: Path) -> None:
    result, follower, graph, lines = fly(tmp_path, "lockstep")
    s = result.summary
    assert result.exit_code == 0, lines
    assert _seen(graph, follower.node.zid)
    run = load_run(result.run_dir)
    ticks = len(run.tick)
    # One odometry per tick, stamped with its sim time, at the world's true pose.
    for rid in SC.robots:
        odom = np.array(follower.odom[rid])
        assert len(odom) == ticks
        np.testing.assert_allclose(odom[:, 0], run.time_s, atol=1e-9)
        row = run.index(rid)
        np.testing.assert_allclose(odom[:, 1:3], run.pose[row, :, :2], atol=1e-4)
        heading = np.angle(np.exp(1j * (odom[:, 3] - run.pose[row, :, 2])))
        assert np.abs(heading).max() < 1e-4
    assert len(follower.tf) == ticks
    # /clock says every tick once, in order; robot 3 answered each.
    assert follower.clocks == pytest.approx([k * SC.dt_s for k in range(len(follower.clocks))])
    assert s["ros2"]["twists"]["3"]["taken"] == len(follower.clocks) == follower.twists
    assert s["ros2"]["twists"]["3"]["rejected"] == 0
    assert s["lockstep_misses"] == 0
    assert s["end_reason"] == "leader_finished"
    rms = s["followers"]["3"]["rms_m"]
    print(f"lockstep: R3 driven from ROS, formation error RMS {rms:.3f} m over {ticks} ticks")
    assert rms < 1.5
    assert any("ROS 2 bridge" in line for line in lines)
    assert any("robot 3 is driven from ROS 2" in line for line in lines)
    # Two lockstep runs, one digest.
    again, _, _, _ = fly(tmp_path, "lockstep")
    assert again.summary["trajectory_digest"] == s["trajectory_digest"]


def test_realtime_driven_from_ros(tmp_path: Path) -> None:
    result, follower, _graph, lines = fly(tmp_path, "realtime")
    s = result.summary
    assert result.exit_code == 0, lines
    assert s["ros2"]["twists"]["3"]["taken"] > 0.9 * len(follower.clocks)
    rms = s["followers"]["3"]["rms_m"]
    print(f"real time: R3 driven from ROS, formation error RMS {rms:.3f} m")
    assert rms < 1.5


def test_a_malformed_payload_and_a_nan_twist_are_rejected_and_counted(tmp_path: Path) -> None:
    from tests.system.rosclient import twist_bytes

    bad = [(0.5, b"\x00\x01\x00\x00garbage"), (0.5, twist_bytes(math.nan, 0.0))]
    result, follower, _graph, lines = fly(tmp_path, "lockstep", duration_s=2.0, before=bad)
    s = result.summary
    assert result.exit_code == 0, lines
    assert s["ros2"]["twists"]["3"]["rejected"] == 2
    assert s["rejected"]["bridge"] == {"malformed CDR": 1, "twist not finite or out of bounds": 1}
    assert s["ros2"]["twists"]["3"]["taken"] == follower.twists == 40
    assert s["lockstep_misses"] == 0
