"""A robot's role built from the scenario: the leader's or a follower's.

The roles (agents.leader_role, agents.follower_role) know nothing of the
scenario file; this hands them its facts, the receiving ends of the robot's
links with the faults the run's schedule puts on them, the leader's policy
(agents.leader_policy.make_policy, by ``leader.policy``) and a follower's
controller (agents.follower.make_controller, by ``controller.law``), each
reset once built (agents.hooks). A controller or policy that cannot be built
or reset (its class raises, or cannot be imported on this machine) fails at
the first tick, as one that raises there does: the robot stops, the run
goes on. No Zenoh here: a test builds a role the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from formation_swarm.agents import hooks
from formation_swarm.agents.controller import ControllerSetup, FollowerController
from formation_swarm.agents.follower import make_controller
from formation_swarm.agents.follower_role import FollowerRole
from formation_swarm.agents.formation import Slot
from formation_swarm.agents.inbox import InboxChecks
from formation_swarm.agents.leader_policy import LeaderParams, LeaderSetup, make_policy
from formation_swarm.agents.leader_role import LeaderRole
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
        return LeaderRole(setup, _built(lambda: make_policy(leader_setup(sc, seed))), law=sc.leader.policy)
    law = sc.followers[rid].law
    slot = sc.formation_by_code(setup.code).slots[rid]
    given = controller
    built = _built(lambda: make_controller(_controller_setup(sc, rid, slot)) if given is None else given)
    formation_link: Link[FormationCode] = _link(sc, "formation", sc.leader.robot_id, rid, seed)
    return FollowerRole(setup, formation_link, built, law=law)


def leader_setup(sc: Scenario, seed: int) -> LeaderSetup:
    """What the leader's policy is built from: the scenario's [leader] keys, its formations, the run's seed."""
    ld = sc.leader
    params = LeaderParams(
        waypoints=ld.waypoints,
        speed_mps=ld.speed_mps,
        turn_rate_rps=ld.turn_rate_rps,
        lookahead_m=ld.lookahead_m,
        corners=ld.corners,
        sensing_range_m=ld.sensing_range_m,
        clear_after_s=ld.clear_after_s,
        code_burst_s=ld.code_burst_s,
        code_period_s=ld.code_period_s,
        policy=ld.policy,
        policy_params=ld.policy_params,
    )
    return LeaderSetup(
        robot_id=ld.robot_id,
        params=params,
        formations=sc.formation_names,
        formation=sc.code_of(ld.formation),
        avoid_formation=None if ld.avoid_formation is None else sc.code_of(ld.avoid_formation),
        dt_s=sc.dt_s,
        width_m=sc.width_m,
        max_wheel_mps=sc.max_wheel_mps,
        seed=seed,
    )


def _controller_setup(sc: Scenario, rid: int, slot: Slot) -> ControllerSetup:
    return ControllerSetup(robot_id=rid, params=sc.followers[rid], slot=slot, max_wheel_mps=sc.max_wheel_mps)


Built = TypeVar("Built")


def _built(build: Callable[[], Built]) -> Built:
    """A controller or policy built and reset (agents.hooks), or one that
    fails at once when either raises."""
    try:
        made = build()
        hooks.reset(made)
    except Exception as exc:  # noqa: BLE001 - a user's class: its failure stops its robot, not the run
        return Unbuilt(exc)  # type: ignore[return-value]
    return made


class Unbuilt:
    """In the place of a controller or policy whose class raised when built
    or reset: its step raises that error again, so the role reports it (with
    its traceback)."""

    def __init__(self, error: Exception) -> None:
        self.error = error

    def step(self, _inp: Any) -> Any:
        raise self.error


def _link(sc: Scenario, kind: str, src: int, rid: int, seed: int) -> Link[Observation] | Link[FormationCode]:
    """The receiving end of ``kind``'s link from ``src`` to robot ``rid``."""
    drop = sc.links.obs_drop if kind == "obs" else sc.links.formation_drop
    return Link(link_name(kind, src, rid), drop, seed, faults_on(sc.faults, kind, rid), sc.dt_s)
