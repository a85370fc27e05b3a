"""examples/ros2_follower without ROS: the pursuit law's geometry, the session
configuration it writes for rmw_zenoh, and the RViz config's frame and topics."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest
import zenoh

from tests.helpers.ros2_example import EXAMPLE, load

pursuit = load("pursuit")
session_config = load("session_config")


def test_the_slot_is_behind_and_right_of_the_reference() -> None:
    north = pursuit.Pose(0.0, 0.0, math.pi / 2)
    assert pursuit.target(north, pursuit.Slot(back_m=1.5, right_m=3.0)) == pytest.approx((3.0, -1.5))
    east = pursuit.Pose(1.0, 2.0, 0.0)
    assert pursuit.target(east, pursuit.Slot(back_m=1.5, right_m=0.0)) == pytest.approx((-0.5, 2.0))


def test_on_its_slot_it_moves_as_the_reference() -> None:
    slot = pursuit.Slot(back_m=1.5, right_m=0.0)
    ref = pursuit.Pose(0.0, 0.0, 0.3)
    tx, ty = pursuit.target(ref, slot)
    # Its lookahead point on the target, heading as the reference: the reference's twist.
    own = pursuit.Pose(tx - slot.lookahead_m * math.cos(0.3), ty - slot.lookahead_m * math.sin(0.3), 0.3)
    assert pursuit.pursue(own, ref, (1.2, 0.0), slot) == pytest.approx((1.2, 0.0))
    behind = own._replace(x_m=own.x_m - math.cos(0.3), y_m=own.y_m - math.sin(0.3))
    speed, turn = pursuit.pursue(behind, ref, (0.8, 0.0), slot)
    assert speed == pytest.approx(0.8 + slot.gain_per_s)  # 1 m behind: faster by the gain
    assert turn == pytest.approx(0.0, abs=1e-12)


def test_answer_picks_the_formations_slot_and_waits_for_poses() -> None:
    poses = {2: pursuit.Pose(0.0, 0.0, math.pi / 2), 3: pursuit.Pose(3.0, -0.3, math.pi / 2)}
    assert pursuit.answer({}, {}, 0) == (0.0, 0.0)
    assert pursuit.answer(poses, {}, 0) == pytest.approx((0.0, 0.0))  # on its triangle slot
    speed, turn = pursuit.answer(poses, {}, 1)  # the line: 1.5 m behind robot 2, to its left
    assert turn > 0
    with pytest.raises(ValueError, match="own must be finite"):
        pursuit.pursue(pursuit.Pose(math.nan, 0.0, 0.0), poses[2], (0.0, 0.0), pursuit.Slot())
    assert speed < pursuit.Slot().max_speed_mps


def test_session_config_nests_the_login_and_zenoh_reads_it(tmp_path: Path) -> None:
    login = {"transport/auth/usrpwd": {"user": "ros2", "password": "pw"}}
    (tmp_path / "ros2.json").write_text(json.dumps(login))
    out = tmp_path / "session.json5"
    assert session_config.main([str(tmp_path / "ros2.json"), "tcp/127.0.0.1:7447", str(out)]) == 0
    conf = json.loads(out.read_text())
    assert conf == {
        "mode": "client",
        "connect": {"endpoints": ["tcp/127.0.0.1:7447"]},
        "scouting": {"multicast": {"enabled": False}},
        "transport": {"auth": {"usrpwd": {"user": "ros2", "password": "pw"}}},
    }
    assert out.stat().st_mode & 0o077 == 0
    assert json.loads(zenoh.Config.from_json5(out.read_text()).get_json("transport/auth/usrpwd/user")) == "ros2"
    assert session_config.main([str(tmp_path / "nope.json"), "tcp/127.0.0.1:7447", str(out)]) == 2
    with pytest.raises(ValueError, match="transport/auth/usrpwd"):
        session_config.session_config({}, "tcp/127.0.0.1:7447")


def test_the_rviz_config_shows_map_tf_odometry_and_cameras() -> None:
    text = (EXAMPLE / "swarm.rviz").read_text()
    assert re.findall(r"Fixed Frame: (\S+)", text) == ["map"]
    assert re.findall(r"Class: rviz_default_plugins/(\w+)", text).count("TF") == 1
    assert re.findall(r"Value: (/robot\d/\w+)", text) == [
        f"/robot{r}/{t}" for r in (1, 2, 3) for t in ("odom", "camera")
    ]
