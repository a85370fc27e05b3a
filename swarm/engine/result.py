"""What an engine's run gives: the summary ``swarm run`` writes
(runtime.summary, from the world's stats and each agent's), its exit code,
and what the roles noted."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from formation_swarm.engine.agents import RUN_ID
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.proc import clean_json
from formation_swarm.spec.scenario import Scenario
from formation_swarm.world.tick import WorldTick


@dataclass(frozen=True)
class EngineResult:
    """A run's outcome: ``summary`` has the keys of ``swarm run``'s
    summary.json (docs/running.md), but for what only processes have
    (their pids, a recording); ``exit_code`` is ``swarm run``'s (0, or 1 for
    a run that lost its leader, every follower, or a follower's controller);
    ``notes`` are the lines an agent process would have logged (a failed
    controller's traceback), each after its agent's name."""

    summary: dict[str, Any] = field(repr=False)
    exit_code: int
    notes: tuple[str, ...] = ()

    @property
    def trajectory_digest(self) -> str:
        """The digest of every robot's pose at every tick: ``swarm run --mode lockstep``'s for the same run."""
        return str(self.summary["trajectory_digest"])

    @property
    def followers(self) -> dict[str, dict[str, Any]]:
        """Each follower's metrics (formation error RMS and max in m, ...), by robot id as text."""
        return dict(self.summary["followers"])

    @property
    def events(self) -> list[dict[str, Any]]:
        """What the engine did to the agents (killed, started, frozen, thawed), as ``swarm run``'s events."""
        return list(self.summary["events"])

    @property
    def end_reason(self) -> str:
        """Why the run ended: ``leader_finished`` or ``duration_reached``."""
        return str(self.summary["end_reason"])

    @property
    def ticks(self) -> int:
        return int(self.summary["ticks"])

    @property
    def world(self) -> dict[str, Any]:
        """The world's own stats (its metrics, final poses, the leader's path, fault log)."""
        return dict(self.summary["parts"]["world"])


def world_stats(tick: WorldTick, *, end_reason: str, ended_at_s: float, wall_s: float) -> dict[str, Any]:
    """The world's stats, as the world process writes them (nodes.world.node)
    less what only a process has (its CPU, its waits, a logger)."""
    out = tick.summary()
    out.update(
        {
            "mode": "lockstep",
            "loop_wall_time_s": wall_s,
            "ticks_per_s": tick.engine.tick / wall_s if wall_s > 0 else math.nan,
            "lockstep_misses": tick.misses,
            "late_answers": tick.late_answers,
            "duplicate_agents": {},
            "late_ticks": 0,
            **tick.faults.stats(),  # deaths, fault_log, rejoins, recoveries
            "robot_digests": tick.robot_digests(),
            "logger_lost": None,
            "stalls": tick.stalls.events,
            "held_for_lost_s": 0.0,
            "leader_done": tick.leader_done,
            "end_reason": end_reason,
            "ended_at_s": ended_at_s,
            "messages": dict(tick.counts),
            "cmd_links": tick.link_stats(),
            "rejected": tick.rejected(),
        }
    )
    return out


def result(
    sc: Scenario, world: Mapping[str, Any], agents: Mapping[str, Any], events: list[dict[str, Any]], notes: list[str]
) -> EngineResult:
    """The run's result from the world's stats and each agent's, as the launcher
    builds it from their files (NaN and inf as None, as JSON has them)."""
    parts = clean_json({"world": world, **agents})
    code = 1 if summary_mod.run_failed(parts, sc) else 0
    summary = summary_mod.build(
        run_id=RUN_ID,
        sc=sc,
        mode="lockstep",
        parts=parts,
        processes={},
        events=events,
        recording=None,
        exit_code=code,
        end_reason=world["end_reason"],
        ended_at_s=world["ended_at_s"],
        interrupted=False,
        timed_out=False,
    )
    return EngineResult(summary=summary, exit_code=code, notes=tuple(notes))
