"""The world's tick (world.tick) driven as its process drives it, without
Zenoh: observations out, decoded commands in, misses, staleness, returns."""

from __future__ import annotations

import pytest

from formation_swarm.protocol.messages import Observation, Truth
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.tick import WorldTick
from tests.helpers import SCENARIOS
from tests.helpers.messages import command

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")  # 1 leads 2 and 3; dt 0.05 s, stale after 0.5 s


def _tick(lockstep: bool = True, faults: tuple[str, ...] = ()) -> WorldTick:
    sc = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml", faults=faults) if faults else FIG11
    return WorldTick(sc, sc.seed, lockstep=lockstep, wall_s=lambda: 0.0)


def _publish(world: WorldTick) -> dict[int, Observation]:
    world.start(0.0)
    return dict(world.observations())


def test_a_lockstep_tick_advances_once_every_live_robot_answered() -> None:
    world = _tick()
    sent = _publish(world)
    assert sorted(sent) == [1, 2, 3]
    assert list(sent)[-1] == 1  # the leader's last: the followers' controllers take longer
    assert {o.tick for o in sent.values()} == {0}
    assert [o.seq for o in sent.values()] == [1, 1, 1]  # one stream per robot
    assert world.waiting() == [1, 2, 3]
    world.command(command(sender=2, seq=1, tick=0, left_mps=0.5, right_mps=0.5))
    world.command(command(sender=1, seq=1, tick=0, left_mps=1.0, right_mps=1.0))
    assert world.waiting() == [3]
    world.command(
        command(sender=3, seq=1, tick=1, left_mps=0.5, right_mps=0.5)
    )  # for a tick not published: not an answer
    assert world.waiting() == [3]
    assert world.rejected() == {"tick ahead of the world": 1}
    world.command(command(sender=3, seq=2, tick=0, left_mps=0.7, right_mps=0.7))
    assert world.waiting() == []
    world.close()
    world.step()
    assert world.engine.tick == 1
    assert world.misses == 0
    assert world.counts == {"obs_sent": 3, "cmd_received": 4, "truth_sent": 0}
    truth = world.truth()  # tick 0's, sent while the agents work on tick 1
    assert isinstance(truth, Truth)
    assert (truth.tick, truth.seq, [r[0] for r in truth.robots]) == (0, 1, [1, 2, 3])
    assert world.truth() is None  # sent once
    assert world.counts["truth_sent"] == 1


def test_a_lockstep_answer_for_a_past_tick_is_late_and_counted_not_taken() -> None:
    world = _tick()
    _publish(world)
    for rid in (1, 2, 3):
        world.command(command(sender=rid, seq=1, tick=0, left_mps=0.5, right_mps=0.5))
    world.close()
    world.step()
    _publish(world)
    world.command(command(sender=2, seq=2, tick=0, left_mps=2.0, right_mps=2.0))  # tick 0 again, a newer seq: late
    assert world.late_answers == 1
    assert world.rejected() == {}
    assert world.engine.robots[2].command == (0.5, 0.5)
    assert world.waiting() == [1, 2, 3]
    world.command(command(sender=2, seq=2, tick=0, left_mps=2.0, right_mps=2.0))  # the same again: a replay now
    assert world.rejected() == {"replayed or reordered": 1}
    assert world.late_answers == 1


def test_a_robot_that_misses_the_deadline_is_counted_and_stopped_for_the_step() -> None:
    world = _tick()
    _publish(world)
    world.command(command(sender=1, seq=1, tick=0, left_mps=1.0, right_mps=1.0))
    world.command(command(sender=3, seq=1, tick=0, left_mps=1.0, right_mps=1.0))
    world.engine.robots[2].command = (1.0, 1.0)  # its last tick's command
    before, other = world.engine.robots[2].pose, world.engine.robots[3].pose
    waiting = world.waiting()
    assert waiting == [2]
    assert not world.thawing(waiting)
    assert world.miss(waiting) == []  # none of them just thawed
    world.close()
    world.step()
    assert world.misses == 1
    assert world.engine.robots[2].pose == before
    assert world.engine.robots[3].pose != other  # the ones that answered drive


def test_a_realtime_command_goes_stale_after_stale_after_s_of_wall_time_and_stops_the_robot() -> None:
    world = _tick(lockstep=False)
    dt, stale = FIG11.dt_s, FIG11.stale_after_s
    world.start(0.0)
    world.command(command(sender=2, seq=1, tick=0, left_mps=1.0, right_mps=1.0))
    assert world.engine.robots[2].command_time_s == 0.0  # stamped with the tick's wall time
    poses = []
    k = 0
    while k * dt <= stale + 2 * dt:
        world.start(k * dt + 0.004)  # the ticks start a little late: staleness is on their wall time
        world.close()
        world.step()
        poses.append(world.engine.robots[2].pose)
        k += 1
    moved = [b != a for a, b in zip(poses, poses[1:], strict=False)]
    # Driven while its command is at most stale_after_s old (+ the 4 ms of the first tick), then stopped.
    assert moved == [True] * 9 + [False] * (len(moved) - 9)
    assert world.engine.robots[2].command == (0.0, 0.0)
    assert world.engine.stale_stops == 1
    assert world.summary()["stale_stops"] == 1


def test_a_realtime_world_stamps_commands_with_the_wall_time_its_tick_started() -> None:
    world = _tick(lockstep=False)
    world.start(3.25)
    world.command(command(sender=3, seq=1, tick=0, left_mps=0.2, right_mps=0.3))
    assert world.engine.robots[3].command_time_s == 3.25
    lock = _tick()
    lock.start(3.25)  # lockstep: sim time, whatever the wall clock says
    lock.command(command(sender=3, seq=1, tick=0, left_mps=0.2, right_mps=0.3))
    assert lock.engine.robots[3].command_time_s == 0.0


def test_a_lost_agent_stops_its_robot_and_a_fresh_one_is_readmitted_when_heard() -> None:
    world = _tick()
    for rid in (1, 2, 3):
        assert world.agent_token(rid, True) is None
    lost = world.agent_token(3, False)
    assert lost == "robot 3 lost its agent at t=0.00 s; stopped until it returns"
    assert 3 not in dict(world.observations())
    assert world.waiting() == [1, 2]
    world.command(command(sender=3, seq=5, tick=0, left_mps=1.0, right_mps=1.0))  # its last command, arriving late
    assert world.engine.robots[3].command == (0.0, 0.0)  # a dead robot does not move
    world.agent_token(3, True)  # a fresh agent
    assert world.readmit(hears=lambda rid: False) == []  # lockstep: its observations would be lost
    assert world.readmit(hears=lambda rid: True) == [3]
    world.command(command(sender=3, seq=1, tick=0, left_mps=0.4, right_mps=0.4))  # it counts from 1 again: taken
    assert world.engine.robots[3].command == (0.4, 0.4)
    assert world.rejected() == {}
    assert [d["cause"] for d in world.faults.deaths] == ["lost"]


def test_after_done_an_agent_leaving_is_not_a_loss() -> None:
    world = _tick()
    world.agent_token(2, True)
    status = world.finish()
    assert (status.state, status.total_ticks) == ("done", FIG11.ticks)
    assert world.agent_token(2, False) is None
    assert world.engine.robots[2].alive


def test_a_restart_is_called_before_the_observations_and_waited_for_in_lockstep_only() -> None:
    for lockstep in (True, False):
        world = _tick(lockstep, faults=("restart agent-3@0.1s after=0.1",))
        world.agent_token(3, True)
        calls = []
        while world.engine.tick < 5:
            for call in world.calls_due():
                msg = world.call_message(call)
                calls.append((msg.tick, msg.action, msg.process, world.apply_call(call)))
            world.close()
            world.step()
        assert calls == [(2, "kill", "agent-3", None), (4, "start", "agent-3", 3 if lockstep else None)]
        assert not world.engine.robots[3].alive


@pytest.mark.parametrize("state", ["running", "done"])
def test_status_counts_its_own_stream(state: str) -> None:
    world = _tick()
    first, second = world.status(state), world.status(state)
    assert (first.seq, second.seq, first.total_ticks) == (1, 2, FIG11.ticks)
    assert dict(world.observations())[2].seq == 1  # observations are numbered apart from status


@pytest.mark.parametrize("lockstep", [True, False])
def test_a_second_answer_to_a_tick_is_a_second_agents_refused_and_counted(lockstep: bool) -> None:
    """One robot, one agent: the first valid answer to a tick is the robot's; a
    newer one for the same tick (another agent flying it) changes nothing."""
    world = _tick(lockstep=lockstep)
    _publish(world)
    first = command(sender=2, seq=7, tick=0, left_mps=0.5, right_mps=0.5)
    world.command(first)
    world.command(command(sender=2, seq=1, tick=0, left_mps=2.0, right_mps=2.0))
    world.command(command(sender=2, seq=9, tick=0, left_mps=2.0, right_mps=-2.0, formation=1))
    assert world.engine.robots[2].command == (0.5, 0.5)
    assert world.engine.robots[2].formation == 0
    assert world.rejected() == {"replayed or reordered": 1}  # older than the first: refused by the gate
    assert world.duplicate_agents == {2: 1}
    assert world.late_answers == 0
    world.command(command(sender=3, seq=1, tick=0, left_mps=0.5, right_mps=0.5))
    assert world.duplicate_agents == {2: 1}  # one answer each: none
