"""The leader's and a follower's roles driven with decoded messages, without
Zenoh: the numbers they send back, the formation codes they take and send,
and the controller API a follower's law sits behind."""

from __future__ import annotations

import math

import pytest

from formation_swarm import (
    ControllerSetup,
    FollowerInput,
    FollowerOutput,
    MarkerReading,
    TargetEstimate,
)
from formation_swarm.agents.follower import BUILT_IN, LAWS, FuzzyController, LpsiController, make_controller
from formation_swarm.agents.follower_role import FollowerRole
from formation_swarm.agents.leader_role import LeaderRole
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.nodes.agent.stats import KEYS as STATS_KEYS
from formation_swarm.nodes.agent.wire import Outbox
from formation_swarm.protocol.messages import Command, FormationCode
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.kinematics import Pose
from tests.helpers import SCENARIOS
from tests.helpers.controllers import ByHand
from tests.helpers.fakes import FakePub, answer, observation

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")  # 1 leads; triangle (code 0), line (code 1)
LINE, TRIANGLE = FIG11.code_of("line"), FIG11.code_of("triangle")
DT = FIG11.dt_s


def _follower(sc: scenario_mod.Scenario, rid: int, controller: object = None) -> FollowerRole:
    role = role_for(sc, rid, sc.seed, controller)  # type: ignore[arg-type]
    assert isinstance(role, FollowerRole)
    return role


def _leader(sc: scenario_mod.Scenario) -> LeaderRole:
    role = role_for(sc, sc.leader.robot_id, sc.seed)
    assert isinstance(role, LeaderRole)
    return role


# -- a follower --------------------------------------------------------------------


def test_a_followers_command_is_its_controllers_wheel_speeds_and_its_telemetry_the_estimate() -> None:
    role = _follower(FIG11, 2)
    by_hand = ByHand(FIG11.followers[2], FIG11.formations["triangle"].slots[2].offset)
    for tick in range(6):
        reading = (2.0 - 0.02 * tick, 0.01 * tick, -0.6)
        got = answer(role, observation(tick, ((3, 1.0, 0.0, 0.0), (1, *reading)), dt_s=DT))
        d = by_hand.step(reading)
        by_hand.prepare()
        cmd, tel, v, target = got.command, got.telemetry, d.values, d.target
        assert tel is not None
        assert target is not None
        assert target.cov_m2 is not None
        assert got.code is None
        assert (cmd.sender, cmd.tick, cmd.formation, cmd.done) == (2, tick, TRIANGLE, False)
        assert (cmd.left_mps, cmd.right_mps) == (d.left_mps, d.right_mps)
        assert (tel.seq, tel.tick, tel.time_s, tel.reference) == (cmd.seq + 1, tick, tick * DT, 1)
        assert (tel.left_mps, tel.right_mps) == (d.left_mps, d.right_mps)
        assert (tel.rho_m, tel.alpha_rad, tel.vn) == (v["rho_m"], v["alpha_rad"], v["vn_mps"])
        assert tel.measured == (v["measured_x_m"], v["measured_y_m"])
        assert tel.estimate == (target.x_m, target.y_m)
        assert tel.target_cov == target.cov_m2
        assert (tel.steering_to, tel.changing, tel.extras) == (0, False, ())
        assert (d.stop, v["ekf_resets"], role.stats()["ekf_resets"]) == (None, 0.0, 0)
    # The numbers themselves: its target 2.38 m away, 87 deg to its left: V_N 1.7 m/s, the right wheel a faster.
    assert (tel.rho_m, tel.alpha_rad) == (pytest.approx(2.3844, abs=1e-4), pytest.approx(-1.5173, abs=1e-4))
    assert (tel.vn, cmd.left_mps, cmd.right_mps) == (pytest.approx(1.7), pytest.approx(1.7), pytest.approx(2.2))


def test_a_follower_that_does_not_see_its_reference_stops_and_says_so() -> None:
    role = _follower(FIG11, 2)
    got = answer(role, observation(0, ((3, 1.0, 0.0, 0.0),), dt_s=DT))  # only robot 3 in view
    assert (got.command.left_mps, got.command.right_mps) == (0.0, 0.0)
    tel = got.telemetry
    assert tel is not None
    assert (tel.measured, tel.estimate, tel.target_cov, tel.rho_m, tel.alpha_rad, tel.vn) == (None,) * 6


def test_only_the_newest_observation_is_answered() -> None:
    role = _follower(FIG11, 2)
    for tick in (0, 1, 2):
        role.take_observation(observation(tick, ((1, 2.0, 0.0, 0.6),), dt_s=DT))
    got = role.answer()
    assert got is not None
    assert got.command.tick == 2
    assert role.answer() is None  # nothing new
    assert (role.stats()["superseded"], role.stats()["answered"], role.stats()["last_tick"]) == (2, 1, 2)


def test_a_code_is_flown_from_the_tick_after_the_one_it_is_stamped_with() -> None:
    role = _follower(FIG11, 3)
    role.take_code(FormationCode(sender=1, seq=1, tick=1, code=LINE))  # arrives before observation 0
    flown = [answer(role, observation(k, ((2, 2.0, 0.0, 0.0),), dt_s=DT)).command.formation for k in range(4)]
    assert flown == [TRIANGLE, TRIANGLE, LINE, LINE]
    assert role.slot.reference == 2  # in the line too: R3 follows R2 (an agent's first line says whom)


def test_a_code_from_a_robot_other_than_the_leader_is_rejected_and_counted() -> None:
    role = _follower(FIG11, 2)
    role.take_code(FormationCode(sender=3, seq=1, tick=0, code=LINE))
    role.take_code(FormationCode(sender=1, seq=1, tick=0, code=7))  # the leader's, but no such formation
    flown = [answer(role, observation(k, ((1, 2.0, 0.0, 0.0),), dt_s=DT)).command.formation for k in range(3)]
    assert flown == [TRIANGLE] * 3
    assert role.rejections.by_reason == {"sender mismatch": 1, "unknown formation": 1}
    assert role.stats()["formation_changes"] == []
    tel = answer(role, observation(3, (), dt_s=DT)).telemetry
    assert tel is not None
    assert tel.rejected == 2


class Recorder:
    """A controller of agents.controller's API: it keeps what it is given,
    drives at fixed speeds, says it holds, gives a target and names values
    of its own."""

    def __init__(self) -> None:
        self.inputs: list[FollowerInput] = []

    def step(self, inp: FollowerInput) -> FollowerOutput:
        self.inputs.append(inp)
        values = {"rho_m": 1.25, "vn_mps": math.nan, "steering_to": 2.0, "ekf_resets": 2.0, "its_own": 7.0}
        target = TargetEstimate(x_m=0.5, y_m=math.inf, cov_m2=(0.01, 0.0, 0.02))
        return FollowerOutput(left_mps=0.5, right_mps=0.6, target=target, stop="holding", values=values)


@pytest.mark.filterwarnings("ignore::formation_swarm.spec.keys.ScenarioWarning")  # R5's chain in the line
def test_a_controller_gets_its_reading_slot_and_ticks_and_its_values_reach_the_telemetry() -> None:
    """Five robots: robot 4 follows robot 2 in the triangle and robot 3 in the line."""
    sc = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml", overrides={"run.robots": 5})
    rec = Recorder()
    role = _follower(sc, 4, rec)
    seen = ((2, 2.2, 0.1, -0.7), (3, 4.1, 0.0, 0.4))
    role.take_code(FormationCode(sender=1, seq=1, tick=0, code=LINE))
    answers = [answer(role, observation(k, seen, dt_s=sc.dt_s)) for k in (0, 1, 2, 5)]
    triangle, line = sc.formations["triangle"].slots[4], sc.formations["line"].slots[4]
    assert [i.reading for i in rec.inputs] == [
        MarkerReading(rho_m=2.2, phi_rad=0.1, beta_rad=-0.7),
        *[MarkerReading(rho_m=4.1, phi_rad=0.0, beta_rad=0.4)] * 3,
    ]
    assert [i.slot for i in rec.inputs] == [triangle, line, line, line]
    assert [(i.slot_moved, i.new_reference) for i in rec.inputs] == [(False, False), (True, True)] + [(False,) * 2] * 2
    assert [(i.ticks, i.dt_s) for i in rec.inputs] == [(1, sc.dt_s)] * 3 + [(3, 3 * sc.dt_s)]
    tel = answers[-1].telemetry
    assert tel is not None
    assert (tel.rho_m, tel.vn, tel.alpha_rad, tel.steering_to, tel.reference, tel.formation) == (
        1.25,
        None,
        None,
        2,
        3,
        LINE,
    )
    assert tel.extras == (("its_own", 7.0),)  # a name of its own: an extra (ekf_resets is the stats', not sent)
    assert (tel.estimate, tel.target_cov) == (None, (0.01, 0.0, 0.02))  # an infinite y: no estimate sent
    assert (answers[-1].command.left_mps, answers[-1].command.right_mps) == (0.5, 0.6)
    stats = role.stats()
    assert (stats["held_ticks"], stats["holds"], stats["waited_ticks"], stats["ekf_resets"]) == (4, [[0, 5]], 0, 2)


def test_the_law_picks_the_controller() -> None:
    assert tuple(BUILT_IN) == LAWS
    lpsi = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml", overrides={"controller.law": "lpsi"})
    assert isinstance(_follower(FIG11, 2).controller, FuzzyController)
    assert isinstance(_follower(lpsi, 2).controller, LpsiController)
    slot = lpsi.formations["triangle"].slots[3]
    made = make_controller(ControllerSetup(robot_id=3, params=lpsi.followers[3], slot=slot, max_wheel_mps=3.0))
    assert isinstance(made, LpsiController)
    assert made.offset == slot.offset


# -- the leader --------------------------------------------------------------------


def _fly_leader(sc: scenario_mod.Scenario, ticks: int, obstacles_from: int | None = None) -> list:
    role = _leader(sc)
    out = []
    for k in range(ticks):
        near = ((2.0, 0.1, 0.5),) if obstacles_from is not None and k >= obstacles_from else ()
        out.append(answer(role, observation(k, pose=(0.0, 0.075 * k, math.pi / 2), obstacles=near, dt_s=sc.dt_s)))
    return out


def test_the_leader_repeats_its_code_every_tick_of_a_burst_then_at_its_period() -> None:
    sc = scenario_mod.load(
        SCENARIOS / "fig11_obstacles.toml", overrides={"leader.code_burst_s": 0.2, "leader.code_period_s": 0.5}
    )  # 4 ticks of burst after a change, then every 10 ticks
    steady = _fly_leader(sc, 36)
    assert [k for k, a in enumerate(steady) if a.code is not None] == [0, 1, 2, 3, 4, 14, 24, 34]
    assert {a.code.code for a in steady if a.code is not None} == {TRIANGLE}
    for a in steady:
        if a.code is not None:
            assert (a.code.sender, a.code.tick, a.code.seq + 1) == (1, a.command.tick, a.command.seq)
    # An obstacle in range from tick 10: the line, and a new burst.
    switched = _fly_leader(sc, 36, obstacles_from=10)
    sent = [(k, a.code.code) for k, a in enumerate(switched) if a.code is not None]
    assert sent == [(k, TRIANGLE) for k in (0, 1, 2, 3, 4)] + [(k, LINE) for k in (10, 11, 12, 13, 14, 24, 34)]
    assert [a.command.formation for a in switched] == [TRIANGLE] * 10 + [LINE] * 26


def test_the_leaders_wheels_are_its_pilots() -> None:
    ld = FIG11.leader
    pilot = PathPilot(ld.waypoints, ld.speed_mps, FIG11.width_m, ld.lookahead_m, ld.turn_rate_rps, corners=ld.corners)
    for k, a in enumerate(_fly_leader(FIG11, 5)):
        want = pilot.step(Pose(0.0, 0.075 * k, math.pi / 2))
        assert (a.command.left_mps, a.command.right_mps, a.command.done) == (*want, False)
    assert want == (pytest.approx(1.5), pytest.approx(1.5))  # straight up its path at its speed


def test_the_roles_and_their_process_fill_the_stats_file_between_them() -> None:
    """Every key of an agent's stats file comes from its role or from its process, none from both."""
    process = {
        "robot",
        "role",
        "lockstep",
        "busy_s",
        "cpu_s",
        "loop_cpu_s",
        "in_step",
        "world_back_after_s",
        "rejected",
        "memory_given_back",
    }
    for role in (_leader(FIG11), _follower(FIG11, 2)):
        assert set(role.stats()) == set(STATS_KEYS) - process, role.NAME
    assert _leader(FIG11).stats()["formation_changes"] == []


def test_the_leaders_code_leaves_before_its_command() -> None:
    """In lockstep the world publishes the next tick once it has the leader's
    command: by then every follower must hold the code."""
    pub = FakePub()  # the command's and the code's: one list shows their order
    outbox = Outbox(1, len(FIG11.robots), pub, FakePub(), pub)
    role = _leader(FIG11)
    outbox.send(answer(role, observation(0, pose=(0.0, 0.0, math.pi / 2), dt_s=DT)))
    code, command = pub.payloads
    assert FormationCode.from_bytes(code).seq + 1 == Command.from_bytes(command).seq
