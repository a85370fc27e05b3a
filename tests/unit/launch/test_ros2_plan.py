"""swarm run --ros2 before anything starts: the scenario's [ros2] table, the
robots left to ROS, the bridge's command line and login, the result line."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from formation_swarm.launch import ros2 as ros2_mod
from formation_swarm.launch.plan import Plan, RunOptions
from formation_swarm.protocol import acl
from formation_swarm.spec.scenario import ScenarioError


def plan(tmp_path: Path, mode: str = "lockstep", external: tuple[int, ...] = (3,), **ros2: object) -> Plan:
    overrides = {f"ros2.{k}": v for k, v in {"bridge": True, **ros2}.items()}
    opts = RunOptions(mode=mode, overrides=overrides, external=external, out=tmp_path / "run", run_id="r1")
    return Plan.make("fig11_obstacles", opts)


def test_the_external_robots_are_left_to_ros_not_to_outside_agents(tmp_path: Path) -> None:
    p = plan(tmp_path)
    assert (p.bridge, p.ros2_robots, p.external, p.own_robots) == (True, (3,), (), [1, 2])
    lines = p.command_lines("tcp/127.0.0.1:7447", {}, remote_agents=False, live=None)
    assert set(lines) == {"world", "logger", "bridge", "agent-1", "agent-2"}
    bridge = lines["bridge"]
    assert bridge[bridge.index("--robot") + 1] == "3"
    assert "--lockstep" in bridge
    assert {"--expect-bridge", "--truth-every-tick"} <= set(lines["world"])
    access = ros2_mod.access(p)
    assert access == acl.RosAccess(domain_id=0, namespace="", robots=(3,), login=True)


def test_without_a_robot_left_to_ros_the_world_sends_the_truth_in_batches(tmp_path: Path) -> None:
    p = plan(tmp_path, external=(), domain_id=5, namespace="fleet")
    world = p.command_lines("tcp/127.0.0.1:7447", {}, remote_agents=False, live=None)["world"]
    assert "--expect-bridge" in world
    assert "--truth-every-tick" not in world
    assert ros2_mod.access(p) == acl.RosAccess(domain_id=5, namespace="fleet", robots=(), login=True)
    realtime = plan(tmp_path, mode="realtime").command_lines("e", {}, remote_agents=False, live=None)
    assert "--truth-every-tick" not in realtime["world"]
    assert "--lockstep" not in realtime["bridge"]


def test_without_the_bridge_nothing_of_ros(tmp_path: Path) -> None:
    p = Plan.make("fig11_obstacles", RunOptions(external=(3,), out=tmp_path / "run", run_id="r1"))
    assert (p.bridge, p.ros2_robots, p.external) == (False, (), (3,))
    assert ros2_mod.access(p) is None
    assert "bridge" not in p.command_lines("e", {}, remote_agents=False, live=None)


@pytest.mark.parametrize(
    ("external", "ros2", "said"),
    [
        ((1,), {}, "robot 1 is the leader"),
        ((3,), {"distro": "humble"}, "only jazzy's wire format"),
        ((3,), {"domain_id": 233}, "ros2.domain_id must be in [0, 232]"),
        ((3,), {"namespace": "a b"}, "ros2.namespace"),
        ((3,), {"domian_id": 1}, "did you mean 'domain_id'"),
    ],
)
def test_a_bad_ros2_run_is_refused_before_anything_starts(
    tmp_path: Path, external: tuple[int, ...], ros2: dict[str, object], said: str
) -> None:
    with pytest.raises((ValueError, ScenarioError), match=said.replace("[", r"\[").replace("]", r"\]")):
        plan(tmp_path, external=external, **ros2)
    assert not (tmp_path / "run").exists()


def test_the_ros_nodes_login_is_written_for_its_owner_only(tmp_path: Path) -> None:
    target = tmp_path / "ros2.json"
    target.write_text("an earlier run's")
    ros2_mod.write_login({"transport/auth/usrpwd": {"user": "ros2", "password": "p"}}, target)
    assert stat.S_IMODE(os.stat(target).st_mode) == 0o600
    assert '"user": "ros2"' in target.read_text()


def test_the_result_line_counts_each_robots_twists() -> None:
    ros2 = {"ticks_published": 60, "twists": {"3": {"taken": 58, "rejected": 2, "unawaited": 1}}}
    assert ros2_mod.result_line(ros2) == (
        "ROS 2 bridge: 60 ticks published; robot 3 driven from ROS: 58 Twists taken, 2 rejected, 1 before their tick"
    )
    assert ros2_mod.result_line({"ticks_published": 9, "twists": {}}).endswith("no robot driven from ROS")


def test_the_bridge_spools_what_it_takes_and_the_console_says_how_long_and_how_to_join(tmp_path: Path) -> None:
    p = plan(tmp_path)
    bridge = p.command_lines("tcp/127.0.0.1:7447", {}, remote_agents=False, live=None)["bridge"]
    assert bridge[bridge.index("--wire-spool") + 1] == str(tmp_path / "run" / "wire" / "bridge.spool")
    said: list[str] = []
    ros2_mod.hand_over(said.append, p, "tcp/127.0.0.1:7447")
    assert "the world waits up to 60 s (--peers-timeout) for a node that publishes" in said[1]
    line = ros2_mod.login_line(Path("runs/ros2.json"), "tcp/127.0.0.1:7447")
    assert "session_config.py runs/ros2.json tcp/127.0.0.1:7447 runs/swarm_session.json5 (" in line


def test_a_ros_node_that_never_came_is_named_with_what_the_bridge_waited_for() -> None:
    world = {"waited_for": {"robots": [3], "missing": "no agent for robot 3 and no ROS 2 bridge", "timeout_s": 5.0}}
    bridge = {"waited_for": {"robots": [3], "missing": ["no ROS subscription to /clock"], "timeout_s": 5.0}}
    said = ros2_mod.never_came({"world": world, "bridge": bridge}, (3,)) or ""
    assert said.startswith("no ROS 2 node came for robot 3 ")
    assert "after 5 s (--peers-timeout)" in said
    assert said.endswith("the bridge waited for: no ROS subscription to /clock")
    assert (ros2_mod.never_came({"world": world}, (3,)) or "").endswith("the bridge waited for: see the bridge's log")
    assert ros2_mod.never_came({"world": world, "bridge": bridge}, (2,)) is None  # not a robot left to ROS
    assert ros2_mod.never_came({"world": {"waited_for": None}}, (3,)) is None
