"""The leader's policy API: its path and when its formation changes.

A policy is a class built from one :class:`LeaderSetup`: the leader's robot
id, the scenario's ``[leader]`` keys (:class:`LeaderParams`), the formations
by code, the tick, the wheels, the run's seed and its own parameters
(``policy_params``). Its ``step`` is called once for every tick the leader
answers, with what its sensors gave it (:class:`LeaderSensing`: its
odometry pose and the obstacles within its sensing range), or None when
nothing reached it this tick (its observation link lost or held it back).
It returns a :class:`LeaderMove`: wheel speeds, the formation code to fly,
whether to send that code to the followers this tick, and whether its path
is done (the run may then end). It may keep state; it does no I/O. The role
(agents.leader_role) owns the rest: the link, the inbox checks, the
messages, a failure.

A policy may also define ``reset()``, called once before its first step,
and ``close()``, called once when its agent stops (agents.hooks).

The paper's policy is :class:`PathLeader`, the policy "path": the scripted
path (agents.pilot.PathPilot), the switch to the avoidance formation near
obstacles and back (agents.leader.FormationSwitch), and the code repeated
every tick after a change and then at a heartbeat (agents.leader.CodeRepeats).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

from formation_swarm.agents.laws import LEADER, PATH, declared_params, find_class
from formation_swarm.agents.leader import CodeRepeats, FormationSwitch
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.common.checks import positive
from formation_swarm.world.kinematics import Pose

__all__ = [
    "BUILT_IN",
    "LeaderMove",
    "LeaderParams",
    "LeaderPolicy",
    "LeaderSensing",
    "LeaderSetup",
    "PathLeader",
    "Pose",
    "make_policy",
    "policy_class",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class LeaderSensing:
    """What the leader's sensors give it at one tick."""

    pose: Pose  # its odometry, world frame
    obstacles: tuple[tuple[float, float, float], ...]  # (distance_m, bearing_rad, radius_m) each


@dataclass(frozen=True, kw_only=True, slots=True)
class LeaderMove:
    """What the leader does at one tick."""

    left_mps: float
    right_mps: float
    formation: int  # the code of the formation it flies
    send_code: bool  # send that code to its followers now
    finished: bool  # its path is done: the run may end


@dataclass(frozen=True, kw_only=True, slots=True)
class LeaderParams:
    """The scenario's ``[leader]`` keys a policy may fly by (the paper's path follower flies by all)."""

    waypoints: tuple[tuple[float, float], ...]  # m; the run starts at the first, heading to the second
    speed_mps: float
    turn_rate_rps: float
    lookahead_m: float
    corners: str  # "pursuit" or "arcs"
    sensing_range_m: float  # the world gives the obstacles this close
    clear_after_s: float
    code_burst_s: float
    code_period_s: float
    policy: str = PATH  # leader.policy: "path" or a policy of the user's (agents.laws)
    # Its parameters ([leader.params], checked against its class), as (name, value) pairs.
    policy_params: tuple[tuple[str, bool | int | float | str], ...] = ()


@dataclass(frozen=True, kw_only=True, slots=True)
class LeaderSetup:
    """What a leader's policy is built from."""

    robot_id: int
    params: LeaderParams
    formations: tuple[str, ...]  # the formations' names, by code
    formation: int  # the code of leader.formation: the run starts in it
    avoid_formation: int | None  # the code of leader.avoid_formation; None: none
    dt_s: float
    width_m: float  # the wheel base
    max_wheel_mps: float  # robot.max_wheel_mps: the world refuses a faster wheel command
    seed: int  # the run's: draw any random number from a generator seeded with it
    # The policy's own parameters: its class's PARAMS with the scenario's [leader.params] over them.
    policy_params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        positive("dt_s", self.dt_s)
        positive("width_m", self.width_m)
        positive("max_wheel_mps", self.max_wheel_mps)
        for name, code in (("formation", self.formation), ("avoid_formation", self.avoid_formation)):
            if code is not None and not 0 <= code < len(self.formations):
                raise ValueError(f"{name} must be a code of formations {self.formations!r}, got {code!r}")


class LeaderPolicy(Protocol):
    """A leader's policy; see the module's docstring."""

    def step(self, sensed: LeaderSensing | None) -> LeaderMove: ...


class PathLeader:
    """The paper's leader: a scripted path, a formation switch, repeated codes.

    Without a sensing it keeps its last wheel speeds and formation."""

    def __init__(self, setup: LeaderSetup) -> None:
        p = setup.params
        self.pilot = PathPilot(
            p.waypoints, p.speed_mps, setup.width_m, p.lookahead_m, p.turn_rate_rps, corners=p.corners
        )
        self.switch = FormationSwitch(setup.formation, setup.avoid_formation, p.clear_after_s, setup.dt_s)
        self.repeats = CodeRepeats(p.code_burst_s, p.code_period_s, setup.dt_s)
        self.code = self.switch.code
        self._wheels = (0.0, 0.0)

    def step(self, sensed: LeaderSensing | None) -> LeaderMove:
        if sensed is not None:
            self.code = self.switch.step(sensed.obstacles)
            self._wheels = self.pilot.step(sensed.pose)
        return LeaderMove(
            left_mps=self._wheels[0],
            right_mps=self._wheels[1],
            formation=self.code,
            send_code=self.repeats.due(self.code),
            finished=self.pilot.finished,
        )


BUILT_IN: dict[str, type] = {PATH: PathLeader}  # one class per name of agents.laws.POLICIES


def policy_class(policy: str) -> type:
    """The class of the policy ``policy`` names (agents.laws.LawError if none)."""
    built_in = BUILT_IN.get(policy)
    return built_in if built_in is not None else find_class(policy, LEADER)


def make_policy(setup: LeaderSetup) -> LeaderPolicy:
    """The policy ``setup.params.policy`` names, built as ``Class(setup)``."""
    cls = policy_class(setup.params.policy)
    # Its declared defaults, the scenario's values over them, the setup's over both.
    params = {**declared_params(cls), **dict(setup.params.policy_params), **setup.policy_params}
    policy: LeaderPolicy = cls(replace(setup, policy_params=params))
    return policy
