"""Every message that crosses the wire, defined once.

Each message is a frozen dataclass encoded with msgpack as an array::

    [tag, version, sender, seq, tick, field_1, field_2, ...]

Messages are built by keyword only (``kw_only``): a record of 19 fields is
one swapped pair away from a silent bug. The wire keeps the fields' order.

The header, the field checkers, the decoder and the rejection counter are in
protocol.codec; batches of logger-bound messages in protocol.batch. Their
public names are importable from here too, so that a user of the protocol
needs one import. docs/protocol/messages.md describes every field for writers of
agents in other languages (tests/packaging/test_protocol_doc.py keeps it true).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, ClassVar

from formation_swarm.protocol.batch import BatchPublisher, pack_batch
from formation_swarm.protocol.codec import (
    BATCH_TAG,
    MAX_BATCH_ITEMS,
    MAX_ITEMS,
    MAX_PAYLOAD_BYTES,
    MAX_TICK,
    VERSION,
    WORLD_ID,
    DecodeError,
    Message,
    Rejections,
    boolean,
    count,
    formation_code,
    int_in,
    named_numbers,
    number,
    numbers,
    one_of,
    opt_number,
    records,
    robot_id,
)
from formation_swarm.protocol.keys import MAX_ROBOT_ID

__all__ = [
    "BATCH_TAG",
    "EXTRA_NAME",
    "MAX_BATCH_ITEMS",
    "MAX_EXTRAS",
    "MAX_ITEMS",
    "MAX_PAYLOAD_BYTES",
    "MAX_TICK",
    "VERSION",
    "WORLD_ID",
    "BatchPublisher",
    "Command",
    "DecodeError",
    "FaultCall",
    "FormationCode",
    "Message",
    "Observation",
    "Rejections",
    "Status",
    "Telemetry",
    "Truth",
    "pack_batch",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class Observation(Message):
    """World -> agent, tick k: what the robot's sensors give it.

    pose: the robot's own odometry (x_m, y_m, theta_rad), world frame.
    readings: markers in view, (robot_id, rho_m, phi_rad, beta_rad) each.
    obstacles: obstacles in sensing range (distance_m, bearing_rad, radius_m),
    only for robots that sense them (the leader).
    """

    time_s: float
    pose: tuple[float, float, float]
    readings: tuple[tuple[int, float, float, float], ...]
    obstacles: tuple[tuple[float, float, float], ...]

    TAG: ClassVar[int] = 1
    SENDERS: ClassVar[tuple[int, int]] = (WORLD_ID, WORLD_ID)
    CHECKS = (number, numbers(3), records(robot_id, number, number, number), records(number, number, number))


@dataclass(frozen=True, slots=True, kw_only=True)
class Command(Message):
    """Agent -> world, answer to tick k: wheel speeds (m/s) and the agent's state.

    formation: the formation code the robot is flying; done: the leader has
    finished its path (the run may end).
    """

    left_mps: float
    right_mps: float
    formation: int
    done: bool

    TAG: ClassVar[int] = 2
    SENDERS: ClassVar[tuple[int, int]] = (1, MAX_ROBOT_ID)
    CHECKS = (number, number, formation_code, boolean)


@dataclass(frozen=True, slots=True, kw_only=True)
class FormationCode(Message):
    """Leader -> one follower: the formation to fly, repeated (agents.leader.CodeRepeats)."""

    code: int

    TAG: ClassVar[int] = 3
    SENDERS: ClassVar[tuple[int, int]] = (1, MAX_ROBOT_ID)
    CHECKS = (formation_code,)


# A Telemetry's extras: a controller's own named values (agents.controller).
MAX_EXTRAS = 16
EXTRA_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,31}")


@dataclass(frozen=True, slots=True, kw_only=True)
class Telemetry(Message):
    """Agent -> logger: a follower's estimator and controller state at tick k.

    Points are in the follower's frame (x right, y ahead), m. None where the
    quantity does not exist this tick (no reading, filter not started).
    target_cov: (xx, xy, yy) of the EKF target estimate, m^2.
    extras: the controller's own values, (name, value) each (at most
    MAX_EXTRAS, names EXTRA_NAME, each once); left off the wire when empty
    (``OPTIONAL``), so the paper's telemetry is what it was before the field.
    """

    time_s: float
    reference: int
    formation: int
    measured: tuple[float, float] | None
    estimate: tuple[float, float] | None
    target_cov: tuple[float, float, float] | None
    rho_m: float | None
    alpha_rad: float | None
    vn: float | None
    left_mps: float
    right_mps: float
    steering_to: int
    changing: bool
    obs_dropped: int
    formation_dropped: int
    rejected: int
    extras: tuple[tuple[str, float], ...] = ()

    TAG: ClassVar[int] = 4
    SENDERS: ClassVar[tuple[int, int]] = (1, MAX_ROBOT_ID)
    OPTIONAL: ClassVar[int] = 1
    CHECKS = (
        number,
        robot_id,
        formation_code,
        numbers(2, True),
        numbers(2, True),
        numbers(3, True),
        opt_number,
        opt_number,
        opt_number,
        number,
        number,
        int_in(0, 3),
        boolean,
        count,
        count,
        count,
        named_numbers(MAX_EXTRAS, EXTRA_NAME),
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class Truth(Message):
    """World -> logger: ground truth at tick k (before the step, after the
    commands of tick k).

    robots: (robot_id, x_m, y_m, theta_rad, alive) each, world frame.
    targets: (follower_id, x_m, y_m) true virtual target of each follower's
    slot in the formation its command of tick k names, world frame.
    """

    time_s: float
    robots: tuple[tuple[int, float, float, float, bool], ...]
    targets: tuple[tuple[int, float, float], ...]

    TAG: ClassVar[int] = 5
    SENDERS: ClassVar[tuple[int, int]] = (WORLD_ID, WORLD_ID)
    CHECKS = (number, records(robot_id, number, number, number, boolean), records(robot_id, number, number))


@dataclass(frozen=True, slots=True, kw_only=True)
class Status(Message):
    """World -> all: progress; state "done" ends the run for every process."""

    time_s: float
    state: str
    total_ticks: int

    TAG: ClassVar[int] = 6
    SENDERS: ClassVar[tuple[int, int]] = (WORLD_ID, WORLD_ID)
    CHECKS = (number, one_of("waiting", "running", "done"), count)


_AGENT = re.compile(r"agent-[1-9][0-9]{0,4}")


def process_name(name: str, v: Any) -> str:
    """A process of a run a fault can hit: ``logger`` or ``agent-N`` (N a robot id)."""
    if type(v) is not str:
        raise DecodeError("wrong type", f"{name} must be a string, got {type(v).__name__}")
    if v == "logger" or (_AGENT.fullmatch(v) and int(v[6:]) <= MAX_ROBOT_ID):
        return v
    raise DecodeError("out of range", f"{name}={v[:40]!r} is neither logger nor agent-<robot id>")


@dataclass(frozen=True, slots=True, kw_only=True)
class FaultCall(Message):
    """World -> the executor of process faults (swarm run's launcher): do
    ``action`` to ``process`` now, at tick k, for fault number ``index`` of the
    scenario's schedule (``[[faults]]`` in start order, formation_swarm.common.faults).

    action: "kill" (SIGKILL), "start" (a fresh process for the same robot),
    "freeze" (SIGSTOP), "thaw" (SIGCONT). The world publishes it before the
    tick's observations, so a run with process faults is reproducible.
    """

    time_s: float
    action: str
    process: str
    index: int

    TAG: ClassVar[int] = 7
    SENDERS: ClassVar[tuple[int, int]] = (WORLD_ID, WORLD_ID)
    CHECKS = (number, one_of("kill", "start", "freeze", "thaw"), process_name, count)
