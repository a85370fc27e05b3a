"""swarm run --ros2 through a ROS 2 client no one here wrote: zenoh-ros2-sdk
(its own keys, attachments, liveliness tokens and RIHS01 hashes), its
message definitions from a local folder (written from rosbags' store), its
session configured by examples/ros2_follower/session_config.py from the
run's ROS login, as docs/ros2.md says for a ROS node."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import uuid
from pathlib import Path

import numpy as np
import pytest

from formation_swarm import load_run
from formation_swarm.launch.launcher import Launch
from formation_swarm.launch.ros2 import write_login

pytest.importorskip("zenoh_ros2_sdk")
rosbags = pytest.importorskip("rosbags.typesys")

pytestmark = pytest.mark.slow

HERE = Path(__file__).resolve().parent
EXAMPLE = HERE.parents[1] / "examples" / "ros2_follower"
TYPES = ("geometry_msgs/msg/Twist", "nav_msgs/msg/Odometry", "rosgraph_msgs/msg/Clock", "std_msgs/msg/UInt8")
TWIST_HASH = "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"


def write_msgs(folder: Path, msgtypes: tuple[str, ...]) -> Path:
    """``<folder>/<pkg>/msg/<Name>.msg`` for each type and what it uses, from rosbags' Jazzy store."""
    store = rosbags.get_typestore(rosbags.Stores.ROS2_JAZZY)
    todo, done = list(msgtypes), set()
    while todo:
        msgtype = todo.pop()
        if msgtype in done:
            continue
        done.add(msgtype)
        text, _ = store.generate_msgdef(msgtype, ros_version=2)
        own, *used = re.split(r"\n=+\nMSG: ", text)
        todo += [block.split("\n", 1)[0].strip().replace("/", "/msg/", 1) for block in used]
        pkg, _, name = msgtype.split("/")
        (folder / pkg / "msg").mkdir(parents=True, exist_ok=True)
        (folder / pkg / "msg" / f"{name}.msg").write_text(own)
    return folder


def test_a_zenoh_ros2_sdk_node_sees_the_run_and_drives_robot_3(tmp_path: Path) -> None:
    msgs = write_msgs(tmp_path / "msgs", TYPES)
    run_id, lines = f"ros2-sdk-{uuid.uuid4().hex[:8]}", []
    launch = Launch(
        "fig11_obstacles",
        overrides={"ros2.bridge": True},
        external=[3],
        out=tmp_path / run_id,
        run_id=run_id,
        progress=lines.append,
        peers_timeout_s=60.0,
    )
    out, log = tmp_path / "heard.json", tmp_path / "client.log"
    with launch:
        login = write_login(launch.login("ros2") or {}, tmp_path / "ros2.json")
        config = tmp_path / "session.json5"
        made = [sys.executable, str(EXAMPLE / "session_config.py"), str(login), launch.endpoint, str(config)]
        subprocess.run(made, check=True, capture_output=True, timeout=30)
        host, port = launch.endpoint.removeprefix("tcp/").rsplit(":", 1)
        env = {**os.environ, "ZENOH_SESSION_CONFIG_URI": str(config)}
        argv = [sys.executable, str(HERE / "ros2_sdk_client.py"), host, port, str(msgs), str(out), "200"]
        with log.open("w") as f:
            client = subprocess.Popen(argv, env=env, stdout=f, stderr=subprocess.STDOUT)
        try:
            result = launch.wait(timeout_s=240.0)
            assert client.wait(timeout=60) == 0, log.read_text()[-2000:]
        finally:
            if client.poll() is None:
                client.kill()
                client.wait()
    s = result.summary
    assert result.exit_code == 0, lines
    heard = json.loads(out.read_text())
    assert heard["type_hashes"]["geometry_msgs/msg/Twist"] == TWIST_HASH  # the SDK's own hash
    run = load_run(result.run_dir)
    ticks = len(run.tick)
    for rid in (1, 2, 3):  # one odometry per tick, stamped with its sim time, at the world's true pose
        odom = np.array(heard["odom"][str(rid)])
        assert odom.shape == (ticks, 3)
        np.testing.assert_allclose(odom[:, 0], run.time_s, atol=1e-9)
        np.testing.assert_allclose(odom[:, 1:], run.pose[run.index(rid), :, :2], atol=1e-4)
    assert len(heard["clock"]) == ticks
    np.testing.assert_allclose(heard["clock"], run.time_s, atol=1e-9)
    assert s["ros2"]["twists"]["3"] == {"taken": heard["twists"], "rejected": 0, "unawaited": 0}
    assert s["lockstep_misses"] == 0
    print(f"zenoh-ros2-sdk drove R3: formation error RMS {s['followers']['3']['rms_m']:.3f} m over {ticks} ticks")
