"""What the world accepts from the wire, one message at a time and without a
network: its tick (world.tick) driven with decoded commands and payloads.
Every rejection is counted by its reason; nothing rejected changes what the
robot does."""

from __future__ import annotations

import math

import pytest

from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.commands import at_last_waypoint
from formation_swarm.world.kinematics import Pose
from formation_swarm.world.tick import WorldTick
from tests.helpers import SCENARIOS
from tests.helpers.fakes import FakeRole
from tests.helpers.messages import command

FIG11 = scenario_mod.load(SCENARIOS / "fig11_obstacles.toml")  # 1 leads; triangle (code 0), line (code 1)
RUN = "inputs-test"


def _world(mode: str = "lockstep") -> WorldTick:
    return WorldTick(FIG11, FIG11.seed, lockstep=mode == "lockstep", wall_s=lambda: 0.0)


def test_lockstep_world_takes_an_answer_only_for_the_tick_it_published() -> None:
    world = _world()
    eng = world.engine
    for _ in range(5):
        eng.step(eng.time_s)
    assert eng.tick == 5
    world.command(command(sender=2, seq=1, tick=4, left_mps=1.0, right_mps=1.0))  # the answer to tick 4, late
    world.command(command(sender=2, seq=2, tick=6, left_mps=1.0, right_mps=1.0))  # to a tick not published yet: refused
    assert not eng.robots[2].answered
    assert eng.robots[2].command == (0.0, 0.0)
    assert world.late_answers == 1
    assert world.rejected() == {"tick ahead of the world": 1}
    world.command(command(sender=2, seq=3, tick=5, left_mps=1.0, right_mps=1.2))
    assert eng.robots[2].answered
    assert eng.robots[2].command == (1.0, 1.2)
    assert world.late_answers == 1
    assert world.counts["cmd_received"] == 3


def test_a_command_with_a_huge_seq_costs_the_real_agent_that_tick_only() -> None:
    """Commands are ordered by (tick, seq), the tick cannot pass the world's, and a
    robot answers a tick once: a plausible forgery with seq 2**53 - 10**6 (a
    stolen login's) that comes before the real answer to its tick is taken for
    that tick (the real one then looks replayed), one that comes after it is a
    second answer, refused; the real agent's next answer is newer either way.
    Ordered by seq alone, every real command after it looked replayed, for the
    rest of the run."""
    world = _world("realtime")
    eng = world.engine
    for _ in range(5):
        eng.step(eng.time_s)
    world.command(command(sender=2, seq=2**53 - 10**6, tick=5, left_mps=2.0, right_mps=2.0))  # the forgery, first
    assert eng.robots[2].command == (2.0, 2.0)
    world.command(
        command(sender=2, seq=10, tick=5, left_mps=1.0, right_mps=1.0)
    )  # the real agent's answer to tick 5: older
    assert world.rejected() == {"replayed or reordered": 1}
    eng.step(eng.time_s)
    world.command(command(sender=2, seq=11, tick=6, left_mps=1.1, right_mps=1.1))  # tick 6: taken
    assert eng.robots[2].command == (1.1, 1.1)
    world.command(
        command(sender=2, seq=2**53 - 10**6 + 1, tick=6, left_mps=2.0, right_mps=2.0)
    )  # the forgery, after the real answer to its tick: a second answer
    assert world.duplicate_agents == {2: 1}
    assert eng.robots[2].command == (1.1, 1.1)
    world.command(command(sender=2, seq=11, tick=6, left_mps=1.1, right_mps=1.1))  # a replay: refused
    world.command(command(sender=2, seq=2**53 - 10**6, tick=9, left_mps=2.0, right_mps=2.0))  # a tick to come: refused
    assert world.rejected() == {"replayed or reordered": 2, "tick ahead of the world": 1}
    eng.step(eng.time_s)
    world.command(command(sender=2, seq=12, tick=7, left_mps=1.2, right_mps=1.2))  # tick 7: taken
    assert eng.robots[2].command == (1.2, 1.2)


def test_the_world_rejects_and_counts_a_command_for_an_unknown_formation() -> None:
    world = _world()
    eng = world.engine
    n = len(FIG11.formation_names)
    world.command(command(sender=2, seq=1, tick=0, left_mps=1.0, right_mps=1.0, formation=n))  # one past the last code
    world.command(command(sender=3, seq=1, tick=0, left_mps=1.0, right_mps=1.0, formation=255))
    assert world.rejected() == {"unknown formation": 2}
    assert [eng.robots[r].answered for r in (2, 3)] == [False, False]
    assert eng.robots[2].command == eng.robots[3].command == (0.0, 0.0)
    world.command(
        command(sender=2, seq=2, tick=0, left_mps=1.0, right_mps=1.0, formation=n - 1)
    )  # the last code: taken
    assert eng.robots[2].command == (1.0, 1.0)
    assert eng.robots[2].formation == n - 1
    assert world.rejected() == {"unknown formation": 2}


def test_realtime_world_takes_the_latest_command_whatever_its_tick() -> None:
    world = _world("realtime")
    for _ in range(5):
        world.engine.step(world.engine.time_s)
    world.command(command(sender=3, seq=1, tick=4, left_mps=0.5, right_mps=0.7))
    assert world.engine.robots[3].command == (0.5, 0.7)
    assert world.late_answers == 0


def test_only_the_leader_at_its_last_waypoint_ends_the_run() -> None:
    """The world takes the leader's "done" on its own truth: a follower's, or
    the leader's before the world sees it at its last waypoint, is a command
    that could not be true, rejected whole and counted."""
    world = _world()
    world.command(command(sender=2, seq=1, tick=0, left_mps=0.0, right_mps=0.0, done=True))
    world.command(command(sender=1, seq=2, tick=0, left_mps=0.0, right_mps=0.0, done=True))
    assert not world.leader_done
    assert world.running
    assert world.rejected() == {"done from a follower": 1, "done before the last waypoint": 1}
    assert not world.engine.robots[1].answered  # its real answer still counts for the tick
    world.engine.robots[1].pose = Pose(0.3, 79.6, 0.0)  # 0.5 m from (0, 80): within its 1 m look-ahead
    world.command(command(sender=1, seq=3, tick=0, left_mps=0.0, right_mps=0.0, done=True))
    assert world.engine.robots[1].answered
    assert world.leader_done
    assert not world.running


@pytest.mark.parametrize(
    ("x", "y", "done"),
    [
        (0.0, 79.0, True),  # 1 m short: within the look-ahead
        (0.0, 78.9, False),
        (5.0, 80.1, True),  # past the end, 5 m to the side: a pilot turned wide ends there
        (5.0, 79.9, False),  # not past it, and beyond the look-ahead
        (0.0, -1.0, False),  # behind the start
    ],
)
def test_the_leader_is_at_its_last_waypoint_within_its_look_ahead_or_past_it(x: float, y: float, done: bool) -> None:
    assert at_last_waypoint(Pose(x, y, 0.0), [(0.0, 0.0), (0.0, 80.0)], within_m=1.0) is done


def test_a_path_that_comes_back_on_itself_is_not_done_where_it_began() -> None:
    path = [(0.0, 0.0), (0.0, 50.0), (0.0, 10.0)]  # the last leg points back over the start
    assert not at_last_waypoint(Pose(0.0, 5.0, 0.0), path, within_m=1.0)  # nearest to the first leg
    assert at_last_waypoint(Pose(0.0, 9.5, math.pi), path, within_m=1.0)


def test_a_payload_is_judged_by_the_key_it_came_on_and_by_the_codec() -> None:
    world = _world()
    good = command(sender=2, seq=1, tick=0, left_mps=1.0, right_mps=1.0).to_bytes()
    world.receive(None, good)  # a key that names no robot
    world.receive(9, good)  # a robot the run does not have
    world.receive(3, good)  # robot 2's command on robot 3's key
    world.receive(2, command(sender=2, seq=2, tick=0, left_mps=math.nan, right_mps=1.0).to_bytes())
    world.receive(2, b"\xc1")
    assert world.rejected() == {"unknown robot": 2, "sender mismatch": 1, "not finite": 1, "not msgpack": 1}
    assert world.counts["cmd_received"] == 0  # none decoded
    assert world.engine.robots[2].command == (0.0, 0.0)
    world.receive(2, good)
    assert world.engine.robots[2].command == (1.0, 1.0)
    assert world.counts["cmd_received"] == 1


def test_wheel_speeds_beyond_the_motors_are_rejected_and_rounding_beyond_them_is_clamped() -> None:
    world = _world("realtime")  # one answer per tick: each command here answers a tick of its own
    eng, lim = world.engine, FIG11.max_wheel_mps
    for _ in range(10):
        eng.step(eng.time_s)
    world.command(command(sender=2, seq=1, tick=1, left_mps=1e308, right_mps=1e308))  # schema-valid, physically absurd
    world.command(command(sender=2, seq=2, tick=2, left_mps=1.0, right_mps=-lim * 1.001))
    assert world.rejected() == {"wheel speed out of bounds": 2}
    assert eng.robots[2].command == (0.0, 0.0)
    for seq, cmd in enumerate(((lim, -lim), (-lim, lim), (0.0, -lim), (-lim, 0.0)), start=3):
        world.command(command(sender=2, seq=seq, tick=seq, left_mps=cmd[0], right_mps=cmd[1]))
        assert eng.robots[2].command == cmd  # at the limit: as sent
    assert world.summary()["clamped_commands"] == 0
    world.command(
        command(sender=2, seq=7, tick=7, left_mps=lim * (1 + 5e-10), right_mps=0.0)
    )  # rounding: run at the limit
    world.command(command(sender=3, seq=1, tick=0, left_mps=0.0, right_mps=-lim * (1 + 5e-10)))
    assert (eng.robots[2].command, eng.robots[3].command) == ((lim, 0.0), (0.0, -lim))
    summary = world.summary()
    assert summary["clamped_commands"] == 2
    keys = list(summary)
    assert keys[keys.index("stale_stops") + 1] == "clamped_commands"  # where the engine's summary had it
    assert world.rejected() == {"wheel speed out of bounds": 2}


def test_the_logger_takes_telemetry_far_ahead_of_its_truth_but_nothing_past_the_runs_end() -> None:
    from types import SimpleNamespace

    from formation_swarm.nodes.logger.main import Logger
    from formation_swarm.protocol.codec import WORLD_ID

    log = Logger(None, FIG11, RUN, None, FakeRole())  # type: ignore[arg-type]  # _fresh needs neither
    assert log._fresh(SimpleNamespace(sender=WORLD_ID, tick=10))
    # A loaded machine: a follower's telemetry batch 500 ticks ahead of the world's truth batch.
    assert log._fresh(SimpleNamespace(sender=2, tick=510))
    last = FIG11.ticks  # 1120: 56 s at 20 Hz
    assert log._fresh(SimpleNamespace(sender=3, tick=last + 2))  # a follower's last telemetry, after "done"
    assert not log._fresh(SimpleNamespace(sender=2, tick=last + 3))
    assert not log._fresh(SimpleNamespace(sender=2, tick=2**53))
    assert not log._fresh(SimpleNamespace(sender=2, tick=510))
    assert log._fresh(SimpleNamespace(sender=2, tick=511))  # a huge tick refused did not mute the robot
    assert log.rejections.by_reason == {"tick past the run's end": 2, "replayed or reordered": 1}
    # A tick far ahead but within the run (a stolen login's) mutes no tick but its own:
    # the real telemetry before it still comes in, and fills the gap it opened.
    assert log._fresh(SimpleNamespace(sender=2, tick=1119))
    assert log._fresh(SimpleNamespace(sender=2, tick=512))
    assert log._fresh(SimpleNamespace(sender=2, tick=513))
    assert not log._fresh(SimpleNamespace(sender=2, tick=512))  # each tick once
    assert log.tick_stats()["2"] == {"first": 510, "last": 1119, "missing": 1119 - 514, "gaps": [[514, 1118]]}
    for tick in range(514, 1119):
        assert log._fresh(SimpleNamespace(sender=2, tick=tick))
    assert log.tick_stats()["2"] == {"first": 510, "last": 1119, "missing": 0, "gaps": []}
    assert not log._fresh(SimpleNamespace(sender=2, tick=1119))  # the real one of that tick: the forgery's
    assert log.rejections.by_reason == {"tick past the run's end": 2, "replayed or reordered": 3}
    # Where ticks were missing, per sender: truth from tick 10, R2 from 510, R3 only its last.
    for tick in (11, 12, 20, 21, 40):
        assert log._fresh(SimpleNamespace(sender=WORLD_ID, tick=tick))
    # A late one fills its gap; one before the first opens one.
    assert log._fresh(SimpleNamespace(sender=WORLD_ID, tick=30))
    assert log._fresh(SimpleNamespace(sender=WORLD_ID, tick=5))
    assert log.tick_stats() == {
        "0": {"first": 5, "last": 40, "missing": 4 + 7 + 17, "gaps": [[6, 9], [13, 19], [22, 29], [31, 39]]},
        "2": {"first": 510, "last": 1119, "missing": 0, "gaps": []},
        "3": {"first": last + 2, "last": last + 2, "missing": 0, "gaps": []},
    }


def test_a_role_says_each_scenario_warning_on_one_line_of_its_own(tmp_path, capsys) -> None:
    import argparse

    from formation_swarm.runtime import process as process_mod
    from formation_swarm.spec import files as scenario_files

    with pytest.warns(scenario_mod.ScenarioWarning):
        slow = scenario_mod.load(SCENARIOS / "fig6_turn_vn_1_5.toml", {"leader.speed_mps": 0.9})
    path = tmp_path / "slow.toml"
    path.write_text(scenario_files.dumps(slow.raw))
    role = process_mod.Process("agent 2", 5.0)
    sc = role.load(argparse.Namespace(run=RUN, scenario=str(path)))
    assert isinstance(sc, scenario_mod.Scenario)
    err = capsys.readouterr().err.splitlines()
    assert len(err) == len(slow.warnings) == 1
    who, what, warning = err[0].split(": ", 2)  # not Python's format, with its source line
    assert (who, what, warning) == ("agent 2", "scenario warning", slow.warnings[0])
