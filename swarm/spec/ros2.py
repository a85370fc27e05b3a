"""A scenario's ``[ros2]`` table, checked: the ROS 2 domain, namespace and
distro that ``swarm run --ros2``'s bridge speaks (docs/ros2.md)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from formation_swarm.protocol.keys import RosKeys
from formation_swarm.spec.checking import check_table
from formation_swarm.spec.keys import ROS2_DISTROS, ROS2_KEYS, ScenarioError


@dataclass(frozen=True)
class Ros2Settings:
    bridge: bool = False
    domain_id: int = 0
    namespace: str = ""
    distro: str = "jazzy"


def ros2_settings(raw: Mapping[str, Any]) -> Ros2Settings:
    """The ``[ros2]`` table of a scenario's TOML tables (defaults when absent);
    ScenarioError naming the key for a bad one."""
    table = check_table(raw.get("ros2"), "ros2", ROS2_KEYS)
    if table["distro"] not in ROS2_DISTROS:
        raise ScenarioError(
            f"ros2.distro: only {', '.join(ROS2_DISTROS)}'s wire format is spoken here, got {table['distro']!r}",
            key="ros2.distro",
            value=table["distro"],
        )
    try:
        RosKeys(table["domain_id"], table["namespace"])
    except ValueError as exc:
        raise ScenarioError(f"ros2.namespace: {exc}", key="ros2.namespace", value=table["namespace"]) from None
    ns = table["namespace"].strip("/")
    return Ros2Settings(bridge=table["bridge"], domain_id=table["domain_id"], namespace=ns, distro=table["distro"])
