"""The ROS 2 bridge's decisions without Zenoh: what it publishes for each
message of the run, and which Twist answers which tick."""

from __future__ import annotations

import math

import pytest

from formation_swarm.nodes.bridge.node import blocks
from formation_swarm.nodes.bridge.role import BridgeRole, CmdOut, RosOut
from formation_swarm.protocol import sightings
from formation_swarm.protocol.batch import pack_batch
from formation_swarm.protocol.messages import WORLD_ID, FormationCode, Observation, Truth
from formation_swarm.ros2 import topics
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.ros2 import Ros2Settings

SC = scenario_mod.load("fig11_obstacles")
DT = SC.dt_s


def obs(tick: int) -> bytes:
    msg = Observation(
        sender=WORLD_ID, seq=tick + 1, tick=tick, time_s=tick * DT, pose=(0, 0, 0), readings=(), obstacles=()
    )
    return msg.to_bytes()


def truth(tick: int, x3: float = 1.5) -> bytes:
    robots = ((1, 0.0, 0.1 * tick, math.pi / 2, True), (2, -1.5, -1.5, math.pi / 2, True), (3, x3, -1.5, 0.0, True))
    targets = ((2, -1.5, -1.0), (3, 1.5, -1.5))
    msg = Truth(sender=WORLD_ID, seq=tick + 1, tick=tick, time_s=tick * DT, robots=robots, targets=targets)
    return pack_batch([msg.to_bytes()])


def code(tick: int, value: int) -> bytes:
    return FormationCode(sender=1, seq=tick + 1, tick=tick, code=value).to_bytes()


def role(lockstep: bool = True, robots: tuple[int, ...] = (3,)) -> BridgeRole:
    return BridgeRole(SC, Ros2Settings(), robots, lockstep=lockstep)


def clocks(out: list[RosOut | CmdOut]) -> list[float]:
    return [o.msg.clock.sec + o.msg.clock.nanosec * 1e-9 for o in out if isinstance(o, RosOut) and o.topic == "/clock"]


def test_lockstep_clock_waits_for_the_tick_before_and_the_first_twist_after_it_answers() -> None:
    b = role()
    assert clocks(b.take_obs(3, obs(0))) == [0.0]
    (cmd,) = b.take_twist(3, 1.0, 0.0)
    assert isinstance(cmd, CmdOut)
    assert (cmd.robot, cmd.command.tick, cmd.command.seq, cmd.command.sender) == (3, 0, 1, 3)
    assert cmd.command.left_mps == cmd.command.right_mps == 1.0
    assert b.take_twist(3, 0.5, 0.0) == []  # no tick awaits it
    assert b.take_obs(3, obs(1)) == []  # tick 0 is not published yet
    out = b.take_truth(truth(0))
    assert [o.topic for o in out][-1] == "/clock"
    assert clocks(out) == [pytest.approx(DT)]
    assert "/robot2/odom" in [o.topic for o in out]
    (cmd,) = b.take_twist(3, 0.0, 1.0)
    half = 0.5 * SC.width_m
    assert (cmd.command.tick, cmd.command.left_mps, cmd.command.right_mps) == (1, -half, half)
    assert b.counts.twists[3] == {"taken": 2, "unawaited": 1}


def test_a_twist_not_finite_or_beyond_any_robot_is_rejected_and_counted() -> None:
    b = role()
    b.take_obs(3, obs(0))
    assert b.take_twist(3, math.nan, 0.0) == []
    assert b.take_twist(3, 0.0, math.inf) == []
    assert b.take_twist(3, 1e6, 0.0) == []
    b.rejected_twist(3, "malformed CDR")
    assert b.counts.twists[3]["rejected"] == 4
    assert dict(b.rejections.by_reason) == {"twist not finite or out of bounds": 3, "malformed CDR": 1}
    assert len(b.take_twist(3, 0.2, 0.0)) == 1  # the tick still awaits its answer


def test_wheel_speeds_stay_within_the_motors() -> None:
    b = role()
    b.take_obs(3, obs(0))
    (cmd,) = b.take_twist(3, 10.0, 0.0)
    assert cmd.command.left_mps == cmd.command.right_mps == SC.max_wheel_mps


def test_a_command_flies_the_newest_code_stamped_before_its_tick() -> None:
    b = role()
    line = SC.code_of("line")
    b.take_code(code(0, line))
    b.take_code(code(1, 0))  # stamped at the tick answered: may or may not have come, so left out
    b.take_code(FormationCode(sender=2, seq=9, tick=0, code=0).to_bytes())  # not the leader's
    b.take_obs(3, obs(0))
    b.take_twist(3, 0.0, 0.0)
    b.take_obs(3, obs(1))
    b.take_truth(truth(0))
    (cmd,) = b.take_twist(3, 0.0, 0.0)
    assert cmd.command.formation == line
    assert dict(b.rejections.by_reason) == {"sender mismatch": 1}


def test_each_truth_gives_one_tick_of_topics_with_the_formation_error() -> None:
    b = role(robots=())
    out = b.take_truth(truth(0)) + b.take_truth(truth(1, x3=2.0)) + b.take_truth(truth(1))
    names = [o.topic for o in out]
    assert names.count("/clock") == names.count("/robot3/odom") == 2
    assert dict(b.rejections.by_reason) == {"replayed or reordered": 1}
    errors = [o.msg.data for o in out if o.topic == "/robot3/formation_error"]
    assert errors == [pytest.approx(0.0), pytest.approx(0.5)]
    odom = [o.msg for o in out if o.topic == "/robot3/odom"][-1]
    assert odom.twist.twist.linear.x == pytest.approx(0.5 / DT)  # moved 0.5 m along its heading in one tick
    assert b.counts.ticks_published == 2


def test_real_time_sends_the_latest_twist_each_tick_while_it_is_fresh() -> None:
    now = [100.0]
    b = BridgeRole(SC, Ros2Settings(), (3,), lockstep=False, clock=lambda: now[0])
    assert clocks(b.take_obs(3, obs(0))) == [0.0]  # no Twist yet: no command
    assert b.take_twist(3, 1.0, 0.0) == []
    b.take_twist(3, 0.5, 0.0)
    for tick in (1, 2):
        cmds = [o for o in b.take_obs(3, obs(tick)) if isinstance(o, CmdOut)]
        assert [(c.command.tick, c.command.left_mps) for c in cmds] == [(tick, 0.5)]
    now[0] += SC.stale_after_s + 0.01  # the ROS node went quiet: its last Twist is not repeated
    assert [o for o in b.take_obs(3, obs(3)) if isinstance(o, CmdOut)] == []
    assert b.counts.twists[3]["taken"] == 2


def test_the_leader_is_not_left_to_ros() -> None:
    with pytest.raises(ValueError, match="leader"):
        role(robots=(1,))


def test_topics_of_a_namespace() -> None:
    b = BridgeRole(SC, Ros2Settings(namespace="fleet"), (), lockstep=True)
    assert {o.topic for o in b.take_truth(truth(0))} >= {"/fleet/clock", "/fleet/robot2/odom", "/fleet/tf"}
    assert topics.cmd_vel(3, "fleet") == "/fleet/robot3/cmd_vel"


def seen(tick: int, robot: int) -> bytes:
    """Robot ``robot``'s observation at ``tick``: it sees robot 1 at 2 m, 0.1 rad to its right."""
    msg = Observation(
        sender=WORLD_ID,
        seq=tick + 1,
        tick=tick,
        time_s=tick * DT,
        pose=(0, 0, 0),
        readings=((1, 2.0, 0.3, 0.1),),
        obstacles=(),
    )
    return msg.to_bytes()


def test_every_robot_s_camera_comes_from_the_world_s_sightings() -> None:
    b = role()  # robot 3 left to ROS; robot 2's camera is shown all the same
    b.take_sightings(sightings.pack([(2, seen(0, 2)), (3, seen(0, 3)), (99, seen(0, 3))])[0])
    out = b.take_truth(truth(0))
    cams = {o.topic: o.msg.markers for o in out if o.topic.endswith("/camera")}
    assert set(cams) == {"/robot1/camera", "/robot2/camera", "/robot3/camera"}
    assert len(cams["/robot1/camera"]) == 1  # its DELETEALL: robot 1's observation was not among them
    arrow = cams["/robot2/camera"][1]
    assert (arrow.id, arrow.pose.position.x, arrow.pose.position.y) == (1, 2.0 * math.cos(0.1), -2.0 * math.sin(0.1))
    assert dict(b.rejections.by_reason) == {"unknown robot": 1}
    # Sightings of a tick whose topics are out come too late: not kept.
    b.take_sightings(sightings.pack([(2, seen(0, 2))])[0])
    assert b.readings == {}


def test_topics_block_in_lockstep_but_the_score_and_never_in_real_time() -> None:
    names = [topics.CLOCK, topics.TF, topics.ODOM, topics.CAMERA, topics.FORMATION]
    assert all(blocks(m, lockstep=True) for m in names)
    assert not blocks(topics.ERROR, lockstep=True)
    assert not any(blocks(m, lockstep=False) for m in [*names, topics.ERROR])
