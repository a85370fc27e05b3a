"""swarm run --ros2: the run seen and robot 3 driven through rmw_zenoh's keys,
by a client written from rmw_zenoh's design (tests.system.rosclient: rosbags'
CDR over plain Zenoh; no import of formation_swarm.ros2) with the pursuit of
examples/ros2_follower. Robot 2's camera on ROS is what robot 2's agent was
sent; the Twists the bridge took are in wire.mcap and in swarm export --mcap;
a ROS node that never comes is named in the run's end."""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from formation_swarm import load_run
from formation_swarm.launch.launcher import Launch, RunResult
from formation_swarm.launch.ros2 import write_login
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Observation
from formation_swarm.report.data import RunData
from formation_swarm.report.ros2bag import export_mcap
from formation_swarm.spec import scenario as scenario_mod
from tests.system.rosclient import STORE, TWIST, Follower, RosNode

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
            follower = Follower(node, 3, SC.robots, law, cameras=(2,))
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
    cameras_are_what_robot_2_was_sent(run, follower)
    twists_are_recorded_and_exported(run, follower, tmp_path)
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


def cameras_are_what_robot_2_was_sent(run: RunData, follower: Follower) -> None:
    """/robot2/camera (robot 2 has its own agent) holds, each tick, the readings
    of the observation robot 2's agent received (wire.mcap), as arrows in base_link."""
    sent: dict[int, tuple[tuple[float, ...], ...]] = {}
    with (run.run_dir / "wire.mcap").open("rb") as f:
        for _s, channel, message in make_reader(f).iter_messages(topics=[Keys(run.summary["run_id"]).obs(2)]):
            if channel.metadata.get("receiver") == "agent-2":
                obs = Observation.from_bytes(message.data)
                sent[obs.tick] = obs.readings
    cams = follower.cameras[2]
    assert len(cams) == len(run.tick) == len(sent)
    arrows = 0
    for stamp, seen in cams:
        readings = sent[round(stamp / SC.dt_s)]
        assert [a[0] for a in seen] == [r[0] for r in readings]
        for (_id, x, y, heading), (_rid, rho, phi, beta) in zip(seen, readings, strict=True):
            assert (x, y, heading) == pytest.approx((rho * math.cos(beta), -rho * math.sin(beta), phi), abs=1e-9)
        arrows += len(seen)
    assert arrows > len(cams)  # robot 2 sees more than one robot a tick on average: the triangle


def twists_are_recorded_and_exported(run: RunData, follower: Follower, tmp_path: Path) -> None:
    """Every Twist robot 3's node sent is in wire.mcap as the bridge took it, and in swarm export --mcap."""
    recorded = []
    with (run.run_dir / "wire.mcap").open("rb") as f:
        for _s, channel, message in make_reader(f).iter_messages():
            if channel.metadata.get("receiver") == "bridge" and "/robot3/cmd_vel/" in channel.topic:
                assert channel.message_encoding == "cdr"
                msg = STORE.deserialize_cdr(message.data, TWIST)
                recorded.append((msg.linear.x, msg.angular.z))
    assert recorded == follower.sent
    counts = export_mcap(run, tmp_path / "run.mcap")
    assert counts["/robot3/cmd_vel"] == len(follower.sent)
    assert counts["/robot3/camera"] == len(run.tick)  # what the bridge was sent for robot 3, recorded
    with (tmp_path / "run.mcap").open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        bag = [(m.linear.x, m.angular.z) for *_r, m in reader.iter_decoded_messages(topics=["/robot3/cmd_vel"])]
    assert bag == follower.sent
    # Robot 3 had no agent of ours: nothing to replay, said in one line.
    argv = [sys.executable, "-m", "formation_swarm.cli", "replay", str(run.run_dir), "--robot", "3"]
    replay = subprocess.run(argv, capture_output=True, text=True, timeout=120, check=False)
    assert replay.returncode == 2, replay.stdout + replay.stderr
    assert "robot 3 was driven from ROS 2" in replay.stderr


def test_a_ros_node_that_never_comes_is_named_and_nothing_stays(tmp_path: Path) -> None:
    """As an outside agent that never connects: exit code 1, the robot and the topics waited for named; the
    logger, which left when the world did, is not blamed; the world says it missed robot 3's commands."""
    out = tmp_path / "run"
    argv = [sys.executable, "-m", "formation_swarm.cli", "run", "fig11_obstacles", "--ros2", "--external", "3"]
    done = subprocess.run(
        [*argv, "--peers-timeout", "3", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    s = json.loads((out / "summary.json").read_text())
    said = (
        "no ROS 2 node came for robot 3 (swarm run --ros2 --external): the world gave up waiting after 3 s "
        "(--peers-timeout); the bridge waited for: no ROS publisher of /robot3/cmd_vel; no ROS subscription to /clock"
    )
    assert (s["end_reason"], s["ended"], s["exit_code"]) == ("peers_timeout", said, 1)
    assert s["parts"]["world"]["waited_for"]["robots"] == [3]
    assert s["parts"]["bridge"]["waited_for"]["robots"] == [3]
    assert [line for line in done.stdout.splitlines() if line.startswith("  ended: ")] == [f"  ended: {said}"]
    assert s["failure"] is None  # the ended line says why; the logger left with the world, before tick 0
    assert not [line for line in done.stdout.splitlines() if line.startswith("  failed: ")]
    assert s["parts"]["world"]["waited_for"]["missing"].startswith("no commands for robot 3 from the ROS 2 bridge")
    left = [p for p in Path("/proc").iterdir() if p.name.isdigit() and _runs(p, s["run_id"])]
    assert left == []


def _runs(proc: Path, run_id: str) -> bool:
    """Whether the process at ``proc`` is one of run ``run_id``'s (its command line names it)."""
    try:
        return run_id in (proc / "cmdline").read_bytes().decode(errors="replace").split("\0")
    except OSError:  # it ended meanwhile
        return False
