"""Every Zenoh key expression of a run, built here and only here.

All keys start with ``swarm/<run>`` so that runs never cross-talk::

    swarm/<run>/robot/<id>/obs        world -> agent    Observation for tick k
    swarm/<run>/robot/<id>/cmd        agent -> world    Command (wheel speeds) for tick k
    swarm/<run>/robot/*/formation     leader -> every follower: FormationCode, one put for all
                                      (each follower's link layer applies its own link's faults)
    swarm/<run>/robot/<id>/telemetry  agent -> logger   Telemetry
    swarm/<run>/world/truth           world -> logger   Truth (true poses and targets)
    swarm/<run>/world/status          world -> all      Status (progress, end of run)
    swarm/<run>/world/faults          world -> launcher FaultCall (kill, start, freeze, thaw a process now)
    swarm/<run>/bridge/sightings      world -> bridge   every robot's Observation of a tick (--ros2 only)
    swarm/<run>/alive/<role>/<id>     liveliness tokens (role: world, agent, logger, launcher, bridge)
    swarm/<run>/robot/wake/cmd        world -> itself   wakes its command loop (local only)

With ``swarm run --ros2``, ROS 2's own keys (rmw_zenoh's, outside the run's)::

    <domain>/<namespace>/<topic>/<type>/<hash>  bridge <-> ROS nodes   a topic's samples (CDR)
    @ros2_lv/<domain>/...                       liveliness tokens of the ROS graph

The full keys are formation_swarm.ros2.rmw's; :class:`RosKeys` gives the
patterns the router's access rules name.

A machine's ``swarm host`` serves every run, so its keys are outside any run's::

    swarmhost/<host>/ctl              launcher -> host  HostRequest queries (info, start, signal, poll, collect, end)
    swarmhost/<host>/alive            liveliness token of the host

An agent reads its inbox ``swarm/<run>/robot/<id>/*`` with one subscriber so
that the order in which observations and formation codes arrive is kept.
docs/protocol/messages.md says who publishes and who subscribes to each key
(tests/packaging/test_protocol_doc.py checks its key table against this module).
"""

from __future__ import annotations

import re
from typing import NamedTuple

ROOT = "swarm"
HOST_ROOT = "swarmhost"
_HOST = re.compile(r"^[a-z][a-z0-9-]{0,26}$")  # a host's login is host-<name>: 32 characters at most
MAX_ROBOT_ID = 10_000
_RUN_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
ROBOT_KINDS = ("obs", "cmd", "telemetry")
ROLES = ("world", "agent", "logger", "launcher", "bridge")


def check_run_id(run_id: str) -> str:
    if not isinstance(run_id, str) or not _RUN_ID.match(run_id):
        raise ValueError(
            f"run id must be 1-64 characters of letters, digits, '_', '.', '-' starting with a letter or digit, "
            f"got {run_id!r}"
        )
    return run_id


def check_robot_id(robot_id: int) -> int:
    if isinstance(robot_id, bool) or not isinstance(robot_id, int) or not 1 <= robot_id <= MAX_ROBOT_ID:
        raise ValueError(f"robot id must be an integer in [1, {MAX_ROBOT_ID}], got {robot_id!r}")
    return robot_id


def check_host_name(name: str) -> str:
    if not isinstance(name, str) or not _HOST.match(name):
        raise ValueError(
            f"host name must be 1-27 lowercase letters, digits or '-' starting with a letter, got {name!r}"
        )
    return name


class HostKeys:
    """The key expressions of one machine's ``swarm host``."""

    def __init__(self, name: str) -> None:
        self.name = check_host_name(name)
        self.prefix = f"{HOST_ROOT}/{name}"

    @property
    def ctl(self) -> str:
        """The host's queryable: every request of protocol.hostmsg."""
        return f"{self.prefix}/ctl"

    @property
    def alive(self) -> str:
        return f"{self.prefix}/alive"


_ROS_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
MAX_ROS_DOMAIN = 232  # ROS 2's highest domain id


class RosKeys:
    """The patterns of ROS 2's keys (rmw_zenoh) in one domain, for the access rules."""

    def __init__(self, domain_id: int, namespace: str = "") -> None:
        if isinstance(domain_id, bool) or not isinstance(domain_id, int) or not 0 <= domain_id <= MAX_ROS_DOMAIN:
            raise ValueError(f"ROS domain id must be an integer in [0, {MAX_ROS_DOMAIN}], got {domain_id!r}")
        parts = namespace.strip("/").split("/") if isinstance(namespace, str) and namespace.strip("/") else []
        if not isinstance(namespace, str) or any(not _ROS_NAME.match(p) for p in parts):
            raise ValueError(f"ROS namespace must be names of letters, digits and '_' joined by '/', got {namespace!r}")
        self.domain = f"{domain_id}"
        self.prefix = "/".join([self.domain, *parts])  # a topic's key starts so (its leading '/' dropped)

    @property
    def topics(self) -> str:
        """Every topic of the domain, whatever its type."""
        return f"{self.domain}/**"

    def cmd_vel(self, robot_id: int) -> str:
        """Robot ``robot_id``'s ``cmd_vel`` topic, any type and hash."""
        return f"{self.prefix}/robot{check_robot_id(robot_id)}/cmd_vel/**"

    @property
    def any_cmd_vel(self) -> str:
        return f"{self.domain}/**/cmd_vel/**"

    @property
    def graph(self) -> str:
        """The ROS graph's liveliness tokens in this domain."""
        return f"@ros2_lv/{self.domain}/**"


class RobotKey(NamedTuple):
    robot_id: int
    kind: str


class Keys:
    """The key expressions of one run."""

    def __init__(self, run_id: str) -> None:
        self.run_id = check_run_id(run_id)
        self.prefix = f"{ROOT}/{run_id}"

    def robot(self, robot_id: int, kind: str) -> str:
        if kind not in ROBOT_KINDS:
            raise ValueError(f"robot key kind must be one of {ROBOT_KINDS}, got {kind!r}")
        return f"{self.prefix}/robot/{check_robot_id(robot_id)}/{kind}"

    def obs(self, robot_id: int) -> str:
        return self.robot(robot_id, "obs")

    def cmd(self, robot_id: int) -> str:
        return self.robot(robot_id, "cmd")

    @property
    def codes(self) -> str:
        """Where the leader puts each formation code, once for all its followers:
        the router hands a copy to every inbox it matches (``robot/<id>/*``).
        One put per code, where one per follower made the leader of a large
        swarm wait on the router at every put (docs/protocol/messages.md)."""
        return f"{self.prefix}/robot/*/formation"

    def telemetry(self, robot_id: int) -> str:
        return self.robot(robot_id, "telemetry")

    def inbox(self, robot_id: int) -> str:
        """Everything addressed to one robot: its observations, and the formation codes (``codes``)."""
        return f"{self.prefix}/robot/{check_robot_id(robot_id)}/*"

    @property
    def all_cmd(self) -> str:
        return f"{self.prefix}/robot/*/cmd"

    @property
    def world_wake(self) -> str:
        """Matched by ``all_cmd`` and by no other subscriber: the world puts on it
        locally to end its wait for commands (a Zenoh channel's recv has no timeout)."""
        return f"{self.prefix}/robot/wake/cmd"

    @property
    def all_telemetry(self) -> str:
        return f"{self.prefix}/robot/*/telemetry"

    @property
    def truth(self) -> str:
        return f"{self.prefix}/world/truth"

    @property
    def status(self) -> str:
        return f"{self.prefix}/world/status"

    @property
    def faults(self) -> str:
        """The world's calls to the process that executes process faults (the launcher)."""
        return f"{self.prefix}/world/faults"

    @property
    def sightings(self) -> str:
        """Every robot's observations of a tick, for the ROS 2 bridge (protocol.sightings)."""
        return f"{self.prefix}/bridge/sightings"

    @property
    def world_all(self) -> str:
        return f"{self.prefix}/world/**"

    @property
    def everything(self) -> str:
        return f"{self.prefix}/**"

    def alive(self, role: str, ident: int | str) -> str:
        if role not in ROLES:
            raise ValueError(f"role must be one of {ROLES}, got {role!r}")
        return f"{self.prefix}/alive/{role}/{ident}"

    @property
    def alive_any(self) -> str:
        """Every liveliness token of the run, whatever the role (the world watches these)."""
        return f"{self.prefix}/alive/*/*"

    def alive_all(self, role: str) -> str:
        if role not in ROLES:
            raise ValueError(f"role must be one of {ROLES}, got {role!r}")
        return f"{self.prefix}/alive/{role}/*"

    def parse_robot(self, key: str) -> RobotKey | None:
        """``swarm/<run>/robot/<id>/<kind>`` -> (id, kind); None for anything else."""
        head = self.prefix + "/robot/"
        if not key.startswith(head):
            return None
        rest = key[len(head) :].split("/")
        if len(rest) != 2 or rest[1] not in ROBOT_KINDS or not rest[0].isdigit():
            return None
        rid = int(rest[0])
        if not 1 <= rid <= MAX_ROBOT_ID:
            return None
        return RobotKey(rid, rest[1])

    def parse_alive(self, key: str) -> tuple[str, str] | None:
        head = self.prefix + "/alive/"
        if not key.startswith(head):
            return None
        parts = key[len(head) :].split("/")
        if len(parts) != 2 or parts[0] not in ROLES:
            return None
        return parts[0], parts[1]
