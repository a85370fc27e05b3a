"""The logger's bookkeeping: the ticks each sender gave (each taken once)
and where ticks were missing, which of the run's peers are there and whose
telemetry has ended, and the CPU its loop spent. No Zenoh, no Rerun: the
logger process (formation_swarm.nodes.logger.main) feeds it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

GAPS_KEPT = 8  # per sender, the first runs of missing ticks kept (the count covers them all)


class TickLedger:
    """Per sender (the world's truth, a follower's telemetry): the ticks taken,
    the first and last, and the runs of ticks missing between. Real time drops
    by design; in lockstep every tick is sent, so a gap is a loss."""

    def __init__(self, last_run_tick: int) -> None:
        self.last_run_tick = last_run_tick  # no tick past it is taken
        self.taken: dict[int, bytearray] = {}  # per sender, 1 at each tick taken
        self.first: dict[int, int] = {}
        self.last: dict[int, int] = {}
        # Per sender, the first GAPS_KEPT runs of ticks missing between two taken
        # ([first, last] missing) and how many ticks were missing in all.
        self.gaps: dict[int, list[list[int]]] = {}
        self.missing: dict[int, int] = {}

    def past_end(self, tick: int) -> bool:
        return tick > self.last_run_tick

    def take(self, sender: int, tick: int) -> bool:
        """Take ``tick`` (at most ``last_run_tick``) from ``sender``, in any
        order; False if it was taken already. Each tick is taken once: a message
        with a tick far ahead (a stolen login's, say) costs the real one of that
        tick alone, where keeping only the newest tick made every later real one
        look replayed."""
        taken = self.taken.get(sender)
        if taken is None:
            taken = self.taken[sender] = bytearray(self.last_run_tick + 1)
        if taken[tick]:
            return False
        taken[tick] = 1
        first, last = self.first.get(sender), self.last.get(sender)
        kept = self.gaps.setdefault(sender, [])
        if first is None or last is None:
            self.first[sender] = self.last[sender] = tick
        elif tick > last:
            if tick > last + 1:
                self.missing[sender] = self.missing.get(sender, 0) + tick - last - 1
                kept.append([last + 1, tick - 1])
            self.last[sender] = tick
        elif tick < first:  # late, before the first: the ticks between are missing now
            if tick < first - 1:
                self.missing[sender] = self.missing.get(sender, 0) + first - tick - 1
                kept.insert(0, [tick + 1, first - 1])
            self.first[sender] = tick
        else:  # late, inside a gap: fills it
            self.missing[sender] -= 1
            _fill(kept, tick)
        del kept[GAPS_KEPT:]
        return True

    def stats(self) -> dict[str, dict[str, Any]]:
        """Per sender ("0": the world's truth, else a follower's telemetry): the
        first and last tick taken, how many were missing between and where
        (swarm.summary.recording_gap says it in words)."""
        return {
            str(sender): {
                "first": self.first.get(sender),
                "last": last,
                "missing": self.missing.get(sender, 0),
                "gaps": self.gaps.get(sender, []),
            }
            for sender, last in sorted(self.last.items())
        }


def _fill(gaps: list[list[int]], tick: int) -> None:
    """Take ``tick`` out of the [first, last] runs of missing ticks it falls in."""
    for i, (a, b) in enumerate(gaps):
        if a <= tick <= b:
            gaps[i : i + 1] = [g for g in ([a, tick - 1], [tick + 1, b]) if g[0] <= g[1]]
            return


@dataclass
class Peers:
    """Who of the run the logger has seen: the world (seen, then gone), the
    robots whose agent's token is alive, and the followers whose telemetry
    stream has ended (its end-of-stream mark taken)."""

    world_seen: bool = False
    world_gone: bool = False
    agents: set[int] = field(default_factory=set)
    ended: set[int] = field(default_factory=set)

    def world(self, present: bool) -> None:
        if present:
            self.world_seen = True
        elif self.world_seen:
            self.world_gone = True

    def agent(self, rid: int, present: bool) -> None:
        (self.agents.add if present else self.agents.discard)(rid)

    def all_ended(self, followers: set[int]) -> bool:
        """Every follower's telemetry has ended: its end-of-stream mark taken, or its agent gone."""
        return followers <= self.ended | (followers - self.agents)


@dataclass
class LoopCpu:
    """CPU time, s, of the logger's loop (the process, all threads) and, of its
    own thread's: taking messages apart and checking them; sending them to Rerun."""

    loop_s: float = 0.0
    drain_s: float = 0.0
    send_s: float = 0.0
