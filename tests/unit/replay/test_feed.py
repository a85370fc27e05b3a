"""A robot's role fed again what it took (replay.feed), checked against the
engine (formation_swarm.Engine): the engine's own run, its agents' inputs and
answers written to a wire recording as the run's receivers take them, replays to the
bit; an observation the robot did not answer is taken but not answered; a
restarted agent's commands end the replay; --set changes the role. No
process is started here."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from formation_swarm import Engine
from formation_swarm.engine.agents import Agents
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Command
from formation_swarm.replay.compare import compare
from formation_swarm.replay.feed import inputs_of, replay, robot_keys, scenario_of
from formation_swarm.replay.wire import Wire, read_wire
from formation_swarm.runtime.wirefile import WireWriter, run_info
from formation_swarm.spec.keys import ScenarioError

TICKS = 120  # 6 s of fig11
FAULTS = ("drop obs:3@1s for=2s p=0.5", "drop formation:2@0.5s for=3s p=0.5")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Wire:
    """A lockstep run of the engine, every message its agents took and sent in a wire recording."""
    path = tmp_path_factory.mktemp("feed") / "wire.mcap"
    engine = Engine("fig11_obstacles", overrides={"run.duration_s": TICKS * 0.05}, faults=FAULTS)
    keys = Keys("engine")  # the engine's run id (engine.agents.RUN_ID)
    rec = WireWriter(path, 0.05, run_info("engine", engine.scenario))
    followers = engine.scenario.follower_ids
    answer = Agents.answer

    def heard_answer(self: Agents, rid: int, payload: bytes) -> Any:
        rec.add(f"agent-{rid}", keys.obs(rid), payload, tick=0, received_ns=0)
        got = answer(self, rid, payload)
        if got is not None:
            if got.code is not None:  # the leader's put, before its command, taken by each follower
                for f in followers:
                    rec.add(f"agent-{f}", keys.codes, got.code.to_bytes(), tick=0, received_ns=0)
            rec.add("world", keys.cmd(rid), got.command.to_bytes(), tick=0, received_ns=0)
        return got

    mp = pytest.MonkeyPatch()
    mp.setattr(Agents, "answer", heard_answer)
    try:
        result = engine.run()
    finally:
        mp.undo()
        rec.close()
    assert result.ticks == TICKS
    return read_wire(path, keep=lambda key: True)


@pytest.mark.parametrize("rid", [1, 2, 3])
def test_each_robot_of_the_engines_run_replays_to_the_bit(recorded: Wire, rid: int) -> None:
    sc = scenario_of(recorded)
    inputs = inputs_of(recorded, rid, takes_codes=rid != sc.leader.robot_id)
    assert sorted(inputs.recorded) == list(range(TICKS))
    assert inputs.restarted_at is None
    out = replay(sc, recorded.seed, recorded.run_id, inputs)
    got = compare(inputs.recorded, out.commands)
    assert (got.ticks, got.differing, got.first) == (TICKS, 0, None)
    assert out.notes == []
    assert out.rejected == {}


def test_the_keys_a_replay_reads(recorded: Wire) -> None:
    k = Keys("engine")
    assert robot_keys(k, 2) == {k.obs(2), k.cmd(2), k.codes}
    assert recorded.by_receiver["agent-3"][k.obs(3)] == recorded.counts[k.obs(3)] == TICKS
    assert recorded.by_receiver["world"][k.cmd(3)] == TICKS
    # The leader's repeats (agents.leader.CodeRepeats), taken by each follower.
    assert 0 < recorded.by_receiver["agent-2"][k.codes] == recorded.by_receiver["agent-3"][k.codes] < TICKS
    assert recorded.counts[k.codes] == 2 * recorded.by_receiver["agent-2"][k.codes]


def test_an_observation_not_answered_is_taken_and_not_answered(recorded: Wire) -> None:
    """Real time: an agent that finds two observations waiting answers the newest."""
    sc = scenario_of(recorded)
    inputs = inputs_of(recorded, 3, takes_codes=True)
    skipped = set(range(40, 60, 3))
    inputs.recorded = {k: c for k, c in inputs.recorded.items() if k not in skipped}
    out = replay(sc, recorded.seed, recorded.run_id, inputs)
    assert sorted(out.commands) == sorted(inputs.recorded)
    # The tick after a skipped one is answered with both ticks' time: dt doubles, so its speeds change.
    got = compare(inputs.recorded, out.commands)
    assert got.first is not None
    assert got.first.tick == 41


def test_a_fresh_agents_commands_end_the_replay(recorded: Wire) -> None:
    k = Keys("engine")
    restart = 80
    messages = []
    for h in recorded.messages:
        c = Command.from_bytes(h.payload) if h.key == k.cmd(2) else None
        if c is not None and c.tick >= restart:  # as a restarted agent numbers them: from 1 again
            h = dataclasses.replace(h, payload=Command(**{**_fields(c), "seq": c.seq - 2 * restart}).to_bytes())
        messages.append(h)
    wire = dataclasses.replace(recorded, messages=messages)
    inputs = inputs_of(wire, 2, takes_codes=True)
    assert (inputs.restarted_at, sorted(inputs.recorded)) == (restart, list(range(restart)))
    out = replay(scenario_of(wire), wire.seed, wire.run_id, inputs)
    assert compare(inputs.recorded, out.commands).identical
    assert sorted(out.commands) == list(range(restart))


def _fields(c: Command) -> dict[str, Any]:
    return {n: getattr(c, n) for n in ("sender", "seq", "tick", "left_mps", "right_mps", "formation", "done")}


def test_a_what_if_changes_the_role_and_a_bad_key_is_refused(recorded: Wire, tmp_path: Path) -> None:
    sc = scenario_of(recorded, {"controller.law": "lpsi"})
    assert sc.followers[2].law == "lpsi"
    inputs = inputs_of(recorded, 2, takes_codes=True)
    got = compare(inputs.recorded, replay(sc, recorded.seed, recorded.run_id, inputs).commands)
    assert got.first is not None
    assert got.first.tick == 0
    assert got.rms_left_mps > 0.1
    with pytest.raises(ScenarioError, match="controller"):
        scenario_of(recorded, {"controller.lw": "lpsi"})
