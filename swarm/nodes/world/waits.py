"""Whom the world waits for before its first tick, in words: when it starts
waiting and, at ``--peers-timeout``, what it missed. A robot driven from ROS 2
has no agent of ours: its commands come from the ROS 2 bridge, which takes the
robot's place (its token and command key) only once a ROS node drives it; so
for such a robot the world misses the bridge's commands, not an agent."""

from __future__ import annotations

from collections.abc import Collection, Sequence


def _robots(ids: Sequence[int]) -> str:
    return f"robot{'s' if len(ids) > 1 else ''} {', '.join(map(str, ids))}"


def waiting_for(robots: Sequence[int], ros2_robots: Collection[int], *, logger: bool, bridge: bool) -> str:
    """What the world waits for, as its first line says it: the agents, the
    commands from the bridge for the robots left to ROS, the logger."""
    agents = [r for r in robots if r not in ros2_robots]
    ros = [r for r in robots if r in ros2_robots]
    said = [f"agent{'s' if len(agents) > 1 else ''} {', '.join(map(str, agents))}"] if agents else []
    if ros:
        said.append(f"the ROS 2 bridge with {_robots(ros)}'s commands (from a ROS node)")
    elif bridge:
        said.append("the ROS 2 bridge")
    if logger:
        said.append("the logger")
    return ", ".join(said[:-1]) + " and " + said[-1] if len(said) > 1 else "".join(said)


def missed(
    absent: Sequence[int], ros2_robots: Collection[int], *, logger: bool, bridge: bool, executor: bool
) -> list[str]:
    """What the world missed at its deadline: ``absent``, the robots with no
    one answering for them; ``logger``, ``bridge``, ``executor``: whether that
    process's token never came."""
    out = []
    if agents := [r for r in absent if r not in ros2_robots]:
        out.append(f"no agent for {_robots(agents)}")
    if ros := [r for r in absent if r in ros2_robots]:
        out.append(
            f"no commands for {_robots(ros)} from the ROS 2 bridge (it sends them once a ROS node drives "
            f"{'them' if len(ros) > 1 else 'it'}: the bridge's log says what it lacked)"
        )
    elif bridge:
        out.append("no ROS 2 bridge")
    if logger:
        out.append("no logger")
    if executor:
        out.append("no executor of the process faults (the launcher's token alive/launcher/0)")
    return out
