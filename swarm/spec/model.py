"""The records a scenario file is read into: the run as a whole
(:class:`Scenario`), its leader, obstacles and link faults. Reading and
checking a file is ``formation_swarm.spec.scenario``'s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

from formation_swarm.agents.follower import FollowerParams
from formation_swarm.agents.formation import Formation
from formation_swarm.common.faults import Fault
from formation_swarm.spec import caveats
from formation_swarm.spec.files import deep_set
from formation_swarm.world.camera import CameraParams


@dataclass(frozen=True)
class Obstacle:
    x_m: float
    y_m: float
    radius_m: float


@dataclass(frozen=True)
class LeaderSpec:
    robot_id: int
    speed_mps: float
    turn_rate_rps: float
    lookahead_m: float
    corners: str
    waypoints: tuple[tuple[float, float], ...]
    sensing_range_m: float
    formation: str
    avoid_formation: str | None
    clear_after_s: float
    code_burst_s: float
    code_period_s: float
    policy: str = "path"  # leader.policy (agents.laws)
    policy_params: tuple[tuple[str, bool | int | float | str], ...] = ()  # [leader.params], checked


@dataclass(frozen=True)
class LinkFaults:
    obs_drop: float = 0.0
    cmd_drop: float = 0.0
    formation_drop: float = 0.0


@dataclass(frozen=True)
class Scenario:
    name: str
    seed: int
    dt_s: float
    duration_s: float
    lockstep_deadline_s: float
    stale_after_s: float
    robots: tuple[int, ...]
    width_m: float
    diameter_m: float
    max_wheel_mps: float
    camera: CameraParams
    leader: LeaderSpec
    formations: Mapping[str, Formation]
    followers: Mapping[int, FollowerParams]
    obstacles: tuple[Obstacle, ...]
    links: LinkFaults
    raw: Mapping[str, Any] = field(repr=False, compare=False)
    faults: tuple[Fault, ...] = ()  # the fault schedule, by start time (formation_swarm.common.faults)
    wheel_noise_mps: float = 0.0  # robot.wheel_noise_mps: every wheel, every tick
    placement: tuple[tuple[int, str], ...] = ()  # [placement]: (robot, host) for runs on hosts

    @cached_property
    def warnings(self) -> tuple[str, ...]:
        """What may make the run say little (spec.caveats); not errors. Derived
        from the fields, once: the loader warns with them, swarm run prints them."""
        return caveats.of(self)

    @cached_property
    def formation_names(self) -> tuple[str, ...]:
        """Formation codes are indices into this tuple (made once: the world
        asks for each robot's formation every tick)."""
        return tuple(self.formations)

    def code_of(self, name: str) -> int:
        return self.formation_names.index(name)

    def formation_by_code(self, code: int) -> Formation:
        return self.formations[self.formation_names[code]]

    @property
    def follower_ids(self) -> tuple[int, ...]:
        return tuple(r for r in self.robots if r != self.leader.robot_id)

    @property
    def ticks(self) -> int:
        return int(round(self.duration_s / self.dt_s))

    def with_seed(self, seed: int) -> Scenario:
        raw = deep_set(self.raw, ("run", "seed"), seed)
        return replace(self, seed=seed, raw=raw)
