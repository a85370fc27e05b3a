"""One robot's role fed again what it took in a run, from the run's wire recording.

A robot's agent takes every message of its inbox as it arrives (its
observations, and a follower's formation codes), in the order they come,
and answers the newest observation taken once the ones that had arrived are
all in (nodes.agent.node). Its commands name the tick they answer. So the
replay hands the role, in the order its agent took them (its agent's
channels in wire.mcap), the robot's observations and the leader's codes,
through the agent's own
``nodes.agent.wire.Router``, and asks it to answer right after each
observation whose tick has a recorded command: an observation the agent
skipped (real time: a newer one had arrived) is taken but not answered, as
it was. The role is built as the agent built it (``nodes.agent.setup.role_for``)
from the scenario and seed of the recording's metadata, with ``--set``
overrides for a what-if.

Only the robot's first agent (receiver agent-N, not agent-N.2) is replayed:
its recorded commands are those the world took from robot N, and commands
whose seq starts again come from a fresh agent (a restart): the replay
stops at its first tick.
"""

from __future__ import annotations

import tomllib
import warnings
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from formation_swarm.agents.role_base import RoleBase
from formation_swarm.nodes.agent.setup import role_for
from formation_swarm.nodes.agent.wire import Router
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Command
from formation_swarm.replay.wire import Heard, Wire
from formation_swarm.runtime.wirefile import stamp
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.files import deep_set
from formation_swarm.spec.keys import MAX_DEPTH, ScenarioError

WORLD = "world"  # the receiver of every robot's commands


def scenario_of(wire: Wire, overrides: Mapping[str, Any] | None = None) -> scenario_mod.Scenario:
    """The scenario as run (the recording's metadata), with ``overrides``
    (dotted keys, as ``--set`` gives them); ScenarioError if it does not load."""
    try:
        raw = tomllib.loads(wire.info["scenario"])
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise ScenarioError(f"{wire.path}: the scenario in its metadata is not valid TOML: {exc}") from None
    for dotted, value in (overrides or {}).items():
        if dotted.count(".") >= MAX_DEPTH:
            raise ScenarioError(f"--set {dotted[:40]!r}: a key of at most {MAX_DEPTH} parts", key=dotted)
        raw = deep_set(raw, tuple(dotted.split(".")), value)
    with warnings.catch_warnings():  # the run's own warnings were said when it ran
        warnings.simplefilter("ignore", scenario_mod.ScenarioWarning)
        return scenario_mod.from_dict(raw)


def robot_keys(keys: Keys, rid: int) -> frozenset[str]:
    """The keys a replay of robot ``rid`` reads: its observations and commands, and the codes."""
    return frozenset((keys.obs(rid), keys.cmd(rid), keys.codes))


@dataclass
class Inputs:
    """What robot ``robot_id`` took and answered in the run."""

    robot_id: int
    inbox: list[Heard]  # its observations and, for a follower, the codes, in the order its first agent took them
    recorded: dict[int, Command]  # by tick: its first agent's command for that tick, as the world took it
    restarted_at: int | None = None  # the first tick of a later agent's commands (a restart), if any
    rejected: Counter[str] = field(default_factory=Counter)  # recorded commands that do not decode


def inputs_of(wire: Wire, rid: int, takes_codes: bool) -> Inputs:
    """Robot ``rid``'s inbox and commands from ``wire`` (read with :func:`robot_keys`)."""
    keys = Keys(wire.run_id)
    obs, cmd, codes, agent = keys.obs(rid), keys.cmd(rid), keys.codes, f"agent-{rid}"
    inbox = [h for h in wire.messages if h.receiver == agent and (h.key == obs or (takes_codes and h.key == codes))]
    found = Inputs(robot_id=rid, inbox=inbox, recorded={})
    rejections = Rejections()
    last_seq = 0
    for h in wire.messages:
        if h.receiver != WORLD or h.key != cmd:
            continue
        if (command := rejections.decode(Command, h.payload, sender=rid)) is None:
            continue
        if command.seq <= last_seq:  # counted from 1 again: a fresh agent
            found.restarted_at = command.tick
            break
        last_seq = command.seq
        found.recorded.setdefault(command.tick, command)
    found.rejected = rejections.by_reason
    return found


@dataclass
class Replayed:
    """The role's answers to the recorded inputs, by tick, and what it noted."""

    commands: dict[int, Command] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # the role's lines for its log (a controller's failure)
    rejected: dict[str, int] = field(default_factory=dict)  # what the role refused of its inputs, by reason


def replay(
    sc: scenario_mod.Scenario,
    seed: int,
    run_id: str,
    inputs: Inputs,
    progress: Callable[[int], None] | None = None,
) -> Replayed:
    """Robot ``inputs.robot_id``'s role, built from ``sc`` and ``seed``, fed its
    recorded inbox; ``progress`` is told each tick answered."""
    role = role_for(sc, inputs.robot_id, seed)
    router = Router(Keys(run_id), role)
    out = Replayed()
    for tick in _feed(router, inputs):
        answer = role.answer()
        if answer is not None:
            out.commands.setdefault(answer.command.tick, answer.command)
            role.prepare()
        _take_notes(role, out)
        if progress is not None:
            progress(tick)
    close = getattr(role, "close", None)  # its controller's or policy's close(), as its process calls it
    if close is not None:
        close()
        _take_notes(role, out)
    out.rejected = dict(role.rejections.by_reason)
    return out


def _feed(router: Router, inputs: Inputs) -> Iterator[int]:
    """Hands the inbox to ``router`` in order; yields each tick to answer once its observation is in."""
    obs_key = router.obs_key
    answered: set[int] = set()
    for h in inputs.inbox:
        got = stamp(h.payload) if h.key == obs_key else None
        tick = None if got is None else got[0]
        if tick is not None and inputs.restarted_at is not None and tick >= inputs.restarted_at:
            return  # a later agent's
        router.take(h.key, h.payload)
        if tick is not None and tick in inputs.recorded and tick not in answered:
            answered.add(tick)
            yield tick


def _take_notes(role: RoleBase, out: Replayed) -> None:
    if role.notes:
        out.notes += role.notes
        role.notes.clear()
