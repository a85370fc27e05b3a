"""What the world reads of a run's description, as Protocols.

The engine, the tick and the process faults take any object shaped like
this; formation_swarm.spec.scenario.Scenario is one (the world layer does
not import it: the spec sits above the world).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

from formation_swarm.common.faults import Fault
from formation_swarm.world.camera import CameraParams


class Place(Protocol):
    """A point of a formation in the leader's frame, m."""

    @property
    def x_m(self) -> float: ...

    @property
    def y_m(self) -> float: ...


class Slot(Protocol):
    """A follower's place: its reference robot and its offset from it (x_m, y_m)."""

    @property
    def reference(self) -> int: ...

    @property
    def offset(self) -> tuple[float, float]: ...


class Formation(Protocol):
    @property
    def slots(self) -> Mapping[int, Slot]: ...

    def slot_positions(self) -> Mapping[int, Place]: ...


class Leader(Protocol):
    @property
    def robot_id(self) -> int: ...

    @property
    def waypoints(self) -> Sequence[tuple[float, float]]: ...

    @property
    def lookahead_m(self) -> float: ...

    @property
    def formation(self) -> str: ...

    @property
    def sensing_range_m(self) -> float: ...


class Obstacle(Protocol):
    @property
    def x_m(self) -> float: ...

    @property
    def y_m(self) -> float: ...

    @property
    def radius_m(self) -> float: ...


class CommandLinks(Protocol):
    @property
    def cmd_drop(self) -> float: ...


class WorldSetup(Protocol):
    """The robots, their bodies, the formations by code, the obstacles, the
    cameras, the fault schedule and the clock's figures of one run."""

    @property
    def dt_s(self) -> float: ...

    @property
    def ticks(self) -> int: ...

    @property
    def stale_after_s(self) -> float: ...

    @property
    def lockstep_deadline_s(self) -> float: ...

    @property
    def robots(self) -> tuple[int, ...]: ...

    @property
    def follower_ids(self) -> tuple[int, ...]: ...

    @property
    def leader(self) -> Leader: ...

    @property
    def width_m(self) -> float: ...

    @property
    def diameter_m(self) -> float: ...

    @property
    def max_wheel_mps(self) -> float: ...

    @property
    def wheel_noise_mps(self) -> float: ...

    @property
    def camera(self) -> CameraParams: ...

    @property
    def obstacles(self) -> Sequence[Obstacle]: ...

    @property
    def faults(self) -> Sequence[Fault]: ...

    @property
    def links(self) -> CommandLinks: ...

    @property
    def formation_names(self) -> tuple[str, ...]: ...

    def code_of(self, name: str) -> int: ...

    def formation_by_code(self, code: int) -> Formation: ...
