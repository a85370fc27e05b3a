"""A robot's role built from the scenario: the leader's or a follower's.

The roles (agents.leader_role, agents.follower_role) know nothing of the
scenario file; this hands them its facts, the receiving ends of the robot's
links with the faults the run's schedule puts on them, the leader's policy
and a follower's controller (agents.follower.make_controller, by
``controller.law``). A controller that cannot be built (its class raises,
or cannot be imported on this machine) fails at the first tick, as one
that raises there does: the robot stops, the run goes on. No Zenoh here: a
test builds a role the same way.
"""

from __future__ import annotations

from formation_swarm.agents.controller import ControllerSetup, FollowerController, FollowerInput, FollowerOutput
from formation_swarm.agents.follower import make_controller
from formation_swarm.agents.follower_role import FollowerRole
from formation_swarm.agents.formation import Slot
from formation_swarm.agents.inbox import InboxChecks
from formation_swarm.agents.leader import CodeRepeats, FormationSwitch
from formation_swarm.agents.leader_policy import PathLeader
from formation_swarm.agents.leader_role import LeaderRole
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.agents.role_base import RoleSetup
from formation_swarm.protocol.links import Link, faults_on, link_name
from formation_swarm.protocol.messages import WORLD_ID, FormationCode, Observation
from formation_swarm.spec.scenario import Scenario


def role_for(
    sc: Scenario, rid: int, seed: int, controller: FollowerController | None = None
) -> LeaderRole | FollowerRole:
    """Robot ``rid``'s role; ``seed`` draws its links' drops and faults.
    ``controller``: a follower's, instead of the one its ``controller.law`` names."""
    if rid not in sc.robots:
        raise ValueError(f"--id {rid} is not a robot of this scenario; robots are {list(sc.robots)}")
    setup = RoleSetup(
        robot_id=rid,
        leader_id=sc.leader.robot_id,
        formations=tuple(sc.formation_by_code(c) for c in range(len(sc.formation_names))),
        code=sc.code_of(sc.leader.formation),
        dt_s=sc.dt_s,
        obs_link=_link(sc, "obs", WORLD_ID, rid, seed),
        checks=InboxChecks(sc.robots, sc.camera.range_m, sc.camera.sigma_rho_m, sc.leader.sensing_range_m, sc.dt_s),
    )
    if rid == sc.leader.robot_id:
        return LeaderRole(setup, _path_leader(sc))
    law = sc.followers[rid].law
    if controller is None:
        controller = _controller(sc, rid, sc.formation_by_code(setup.code).slots[rid])
    formation_link: Link[FormationCode] = _link(sc, "formation", sc.leader.robot_id, rid, seed)
    return FollowerRole(setup, formation_link, controller, law=law)


def _controller(sc: Scenario, rid: int, slot: Slot) -> FollowerController:
    """Follower ``rid``'s controller, or one that fails at once when it cannot be built."""
    setup = ControllerSetup(robot_id=rid, params=sc.followers[rid], slot=slot, max_wheel_mps=sc.max_wheel_mps)
    try:
        return make_controller(setup)
    except Exception as exc:  # noqa: BLE001 - a user's class: its failure stops its robot, not the run
        return Unbuilt(exc)


class Unbuilt:
    """In the place of a controller whose class raised when built: its step
    raises that error again, so the role reports it (with its traceback)."""

    def __init__(self, error: Exception) -> None:
        self.error = error

    def step(self, inp: FollowerInput) -> FollowerOutput:
        raise self.error


def _link(sc: Scenario, kind: str, src: int, rid: int, seed: int) -> Link[Observation] | Link[FormationCode]:
    """The receiving end of ``kind``'s link from ``src`` to robot ``rid``."""
    drop = sc.links.obs_drop if kind == "obs" else sc.links.formation_drop
    return Link(link_name(kind, src, rid), drop, seed, faults_on(sc.faults, kind, rid), sc.dt_s)


def _path_leader(sc: Scenario) -> PathLeader:
    """The paper's leader: the scenario's path, formation switch and code repeats."""
    ld = sc.leader
    pilot = PathPilot(ld.waypoints, ld.speed_mps, sc.width_m, ld.lookahead_m, ld.turn_rate_rps, corners=ld.corners)
    avoid = None if ld.avoid_formation is None else sc.code_of(ld.avoid_formation)
    switch = FormationSwitch(sc.code_of(ld.formation), avoid, ld.clear_after_s, sc.dt_s)
    repeats = CodeRepeats(ld.code_burst_s, ld.code_period_s, sc.dt_s)
    return PathLeader(pilot, switch, repeats)
