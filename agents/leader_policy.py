"""The leader's policy API: its path and when its formation changes.

A policy's ``step`` is called once for every tick the leader answers, with
what its sensors gave it (:class:`LeaderSensing`: its odometry pose and the
obstacles within its sensing range), or None when nothing reached it this
tick (its observation link lost or held it back). It returns a
:class:`LeaderMove`: wheel speeds, the formation code to fly, whether to
send that code to the followers this tick, and whether its path is done
(the run may then end). It may keep state; it does no I/O. The role
(agents.leader_role) owns the rest: the link, the inbox checks, the
messages.

The paper's policy is :class:`PathLeader`: the scripted path
(agents.pilot.PathPilot), the switch to the avoidance formation near
obstacles and back (agents.leader.FormationSwitch), and the code repeated
every tick after a change and then at a heartbeat (agents.leader.CodeRepeats).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from formation_swarm.agents.leader import CodeRepeats, FormationSwitch
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.world.kinematics import Pose


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


class LeaderPolicy(Protocol):
    """A leader's policy; see the module's docstring."""

    def step(self, sensed: LeaderSensing | None) -> LeaderMove: ...


class PathLeader:
    """The paper's leader: a scripted path, a formation switch, repeated codes.

    Without a sensing it keeps its last wheel speeds and formation."""

    def __init__(self, pilot: PathPilot, switch: FormationSwitch, repeats: CodeRepeats) -> None:
        self.pilot = pilot
        self.switch = switch
        self.repeats = repeats
        self.code = switch.code
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
