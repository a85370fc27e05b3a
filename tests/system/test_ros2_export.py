"""swarm export --mcap of a short fig11 lockstep run, read back by
mcap-ros2-support (a reader we did not write): the topics, one message per
tick (per robot), and the numbers of the run's own recording."""

from __future__ import annotations

import itertools
import math
import re
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from formation_swarm import load_run
from formation_swarm.launch.launcher import Launch
from formation_swarm.protocol.messages import Observation
from formation_swarm.replay.wire import read_wire
from formation_swarm.report.export import main as export
from formation_swarm.ros2.topics import motion
from tests.helpers import SCENARIOS

pytestmark = pytest.mark.slow
TICKS = 40  # 2 s at dt 0.05


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ros2") / "fig11-s4"
    overrides = {"run.duration_s": TICKS * 0.05}
    with Launch(
        SCENARIOS / "fig11_obstacles.toml", seed=4, out=out, overrides=overrides, progress=lambda _l: None
    ) as la:
        res = la.wait(timeout_s=120.0)
    assert res.exit_code == 0
    return res.run_dir


@pytest.fixture(scope="module")
def bag(run_dir: Path) -> Path:
    assert export([str(run_dir), "--mcap"]) == 0
    return run_dir / "run.mcap"


def test_every_topic_has_one_message_per_tick(bag: Path) -> None:
    counts = Counter(m.topic for m in read_ros2_messages(bag))
    per_tick = ["/clock", "/tf", "/formation"]
    per_robot = [f"/robot{n}/{t}" for n in (1, 2, 3) for t in ("odom", "camera")]
    per_follower = ["/robot2/formation_error", "/robot3/formation_error"]
    assert counts == dict.fromkeys(per_tick + per_robot + per_follower, TICKS)
    with bag.open("rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
    assert summary is not None
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
    assert {s.name for s in summary.schemas.values()} >= {"nav_msgs/msg/Odometry", "tf2_msgs/msg/TFMessage"}


def test_odometry_and_tf_are_the_runs_trajectory(run_dir: Path, bag: Path) -> None:
    run = load_run(run_dir)
    for robot in run.robots:
        msgs = list(read_ros2_messages(bag, topics=[f"/robot{robot}/odom"]))
        pose = np.array(
            [
                [m.ros_msg.pose.pose.position.x, m.ros_msg.pose.pose.position.y, _yaw(m.ros_msg.pose.pose.orientation)]
                for m in msgs
            ]
        )
        assert np.array_equal(pose[:, :2], run.pose[run.index(robot), :, :2])
        assert np.max(np.abs(pose[:, 2] - run.pose[run.index(robot), :, 2])) < 1e-12
        assert [m.log_time_ns for m in msgs] == [round(t * 1e9) for t in run.time_s]
        assert {m.ros_msg.child_frame_id for m in msgs} == {f"robot{robot}/base_link"}
        twists = [(m.ros_msg.twist.twist.linear.x, m.ros_msg.twist.twist.angular.z) for m in msgs]
        poses = run.pose[run.index(robot)].tolist()
        assert twists[0] == (0.0, 0.0)
        expected = [motion(a, b, run.dt_s) for a, b in itertools.pairwise(poses)]
        assert np.max(np.abs(np.subtract(twists[1:], expected))) < 1e-9
    tf = [m.ros_msg for m in read_ros2_messages(bag, topics=["/tf"])]
    last = {t.child_frame_id: t.transform.translation for t in tf[-1].transforms}
    assert (last["robot3/base_link"].x, last["robot3/base_link"].y) == tuple(run.pose[run.index(3), -1, :2])
    clock = [m.ros_msg.clock for m in read_ros2_messages(bag, topics=["/clock"])]
    assert [c.sec + c.nanosec * 1e-9 for c in clock] == pytest.approx(run.time_s.tolist(), abs=1e-9)


def test_errors_formation_and_sightings_are_the_runs(run_dir: Path, bag: Path) -> None:
    run = load_run(run_dir)
    for robot in run.followers:
        err = [m.ros_msg.data for m in read_ros2_messages(bag, topics=[f"/robot{robot}/formation_error"])]
        assert err == run.formation_error_m[run.index(robot)].tolist()
    assert {m.ros_msg.data for m in read_ros2_messages(bag, topics=["/formation"])} == {0}  # the triangle
    wire = read_wire(run_dir / "wire.mcap", keep=lambda key: key.endswith("/robot/2/obs"))
    seen = [len(Observation.from_bytes(h.payload).readings) for h in wire.messages if h.receiver == "agent-2"]
    markers = [len(m.ros_msg.markers) - 1 for m in read_ros2_messages(bag, topics=["/robot2/camera"])]
    assert markers == seen[:TICKS]
    assert sum(markers) > 0


def test_an_existing_out_is_left_alone(run_dir: Path, bag: Path, tmp_path: Path) -> None:
    before = bag.read_bytes()
    assert export([str(run_dir), "--mcap", "--out", str(bag)]) == 2
    assert bag.read_bytes() == before
    assert export([str(run_dir), "--mcap", "--out", str(bag), "--force"]) == 0
    assert export([str(tmp_path / "nowhere"), "--mcap", "--out", str(tmp_path / "x.mcap")]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == []


class _Decoded(NamedTuple):
    topic: str
    log_time_ns: int
    ros_msg: Any


def read_ros2_messages(bag: Path, topics: list[str] | None = None) -> list[_Decoded]:
    """Every message of ``topics`` (all: None), decoded by mcap-ros2-support."""
    with bag.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [_Decoded(c.topic, m.log_time, msg) for _, c, m, msg in reader.iter_decoded_messages(topics=topics)]


def _yaw(q: object) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))  # type: ignore[attr-defined]


def test_rerun_reads_every_topic_with_its_ros2_decoders(bag: Path, tmp_path: Path) -> None:
    rerun = Path(sys.executable).with_name("rerun")
    rrd = tmp_path / "run.rrd"
    convert = [str(rerun), "mcap", "convert", str(bag), "--disable-raw-fallback", "-o", str(rrd)]
    subprocess.run(convert, check=True, capture_output=True, timeout=120)
    stats = subprocess.run(
        [str(rerun), "rrd", "stats", str(rrd)], check=True, capture_output=True, text=True, timeout=120
    )
    entities = set(re.findall(r"^(/\w+(?:/\w+)?): \d+$", stats.stdout, re.MULTILINE)) - {"/__mcap_properties"}
    topics = {m.topic for m in read_ros2_messages(bag)}
    assert entities == topics


def test_a_cut_or_missing_wire_recording_leaves_the_cameras_short(run_dir: Path, bag: Path, tmp_path: Path) -> None:
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy, ignore=shutil.ignore_patterns("*.mcap", "secrets"))
    whole = (run_dir / "wire.mcap").read_bytes()
    (copy / "wire.mcap").write_bytes(whole[: len(whole) // 2])
    assert export([str(copy), "--mcap", "--out", str(tmp_path / "cut.mcap")]) == 0
    (copy / "wire.mcap").unlink()
    assert export([str(copy), "--mcap", "--out", str(tmp_path / "none.mcap")]) == 0
    full = [len(m.ros_msg.markers) for m in read_ros2_messages(bag, topics=["/robot2/camera"])]
    cut = [len(m.ros_msg.markers) for m in read_ros2_messages(tmp_path / "cut.mcap", topics=["/robot2/camera"])]
    none = [len(m.ros_msg.markers) for m in read_ros2_messages(tmp_path / "none.mcap", topics=["/robot2/camera"])]
    assert none == [1] * TICKS  # the DELETEALL alone
    assert len(cut) == TICKS
    assert all(c in (1, f) for c, f in zip(cut, full, strict=True))
