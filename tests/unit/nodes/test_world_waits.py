"""What the world says it waits for and, at its deadline, what it missed
(nodes.world.waits): a robot left to ROS 2 misses the bridge's commands, not an agent."""

from __future__ import annotations

from formation_swarm.nodes.world.waits import missed, waiting_for


def test_the_first_line_names_the_bridges_robots_apart_from_the_agents() -> None:
    said = waiting_for((1, 2, 3), (3,), logger=True, bridge=True)
    assert said.startswith("agents 1, 2, the ROS 2 bridge with robot 3's commands (from a ROS node)")
    assert said.endswith(" and the logger")
    assert waiting_for((1, 2, 3), (), logger=True, bridge=False).startswith("agents 1, 2, 3 and ")
    assert waiting_for((1, 2, 3), (), logger=False, bridge=True).endswith("3 and the ROS 2 bridge")
    assert waiting_for((1,), (), logger=False, bridge=False) == "agent 1"


def test_a_ros_robot_with_no_node_is_missed_as_the_bridges_commands_not_an_agent() -> None:
    said = missed([3], (3,), logger=False, bridge=True, executor=False)
    assert len(said) == 1  # not "no ROS 2 bridge" besides: the bridge's token comes with robot 3's
    assert said[0].startswith("no commands for robot 3 from the ROS 2 bridge (it sends them once a ROS node drives it")
    both = missed([2, 3, 4], (3, 4), logger=True, bridge=True, executor=False)
    assert len(both) == 3
    assert both[0].endswith("agent for robot 2")
    assert both[1].startswith("no commands for robots 3, 4 from ")
    assert both[2] == "no logger"
    alone = missed([], (), logger=False, bridge=True, executor=True)
    assert len(alone) == 2
    assert alone[0].endswith("ROS 2 bridge")
    assert alone[1].startswith("no executor of the process faults")
    assert missed([1, 2], (), logger=False, bridge=False, executor=False)[0].endswith("robots 1, 2")
