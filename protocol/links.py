"""Directed links and their faults, applied by our own link layer.

Every directed link (world -> agent observations, agent -> world commands,
leader -> follower formation codes) has a steady drop probability (the
scenario's ``[links]``) and takes the link faults of the run's schedule that
name it (formation_swarm.common.faults: ``drop``, ``burst``, ``delay``,
``duplicate``, ``reorder``, and ``partition`` for the links it cuts). Every
random decision is a pure function of (seed, link, seq) and, for a fault, of
its text (``fault_key``), so the same run loses, holds and repeats the same
messages however the machine is loaded; the time windows of the faults are
counted in ticks of the message (its sim tick), never in wall time.

Faults are applied by the receiver: the message crosses Zenoh (so a lockstep
tick still completes) and the receiving link layer decides what its process
gets now. ``Link.deliver(seq, tick, item)`` takes one arrival and returns the
list the receiver handles now, in order:

- the held (delayed) messages whose release tick is ``tick`` or earlier,
- then the arrival itself: nothing if it is lost (steady drop, ``drop``,
  ``burst``, ``partition``) or held (``delay``, ``reorder``), twice if it is
  duplicated,
- then the message a ``reorder`` held back at the link's previous arrival
  (so ``[next, held]``).

``Link.due(tick)`` returns the delayed messages whose release tick has come
when no message arrives: the receiver calls it as its own tick advances. A
delay has a resolution of one tick in both modes (``ms`` are rounded up to
whole ticks with dt): a held message comes out when a later message of the
link arrives or the receiver's tick advances, never in between. While a
partition is active everything the link would hand over is lost: the
arrivals of its window and the held messages whose release falls in it.

What a duplicated or reordered message does is up to the receiver's own
checks: ours take a message only if it is newer than the last one taken from
the link, and count the others as "replayed or reordered"
(docs/protocol/links-and-faults.md).
"""

from __future__ import annotations

import collections
import hashlib
import heapq
import math
import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from formation_swarm.common.checks import positive, probability
from formation_swarm.common.faults import Fault, link_faults

_SCALE = float(2**64)
T = TypeVar("T")

# What happened to messages, as counted per link and per fault.
DROPPED = "dropped"  # lost: the steady drop probability, a drop fault or a burst
PARTITIONED = "partitioned"  # lost to a partition
# A fault window's counts at the receiver are final this many ticks after it
# ends: a message stamped with its last tick may arrive after the observation
# of the next (a formation code and the observation take different paths).
COUNTS_FINAL_AFTER_TICKS = 2
DELAYED = "delayed"  # held for a number of ticks
DUPLICATED = "duplicated"  # handed over twice
REORDERED = "reordered"  # held until the link's next message had been handed over
EFFECTS = (DROPPED, PARTITIONED, DELAYED, DUPLICATED, REORDERED)
LINK_KINDS = ("drop", "burst", "delay", "duplicate", "reorder", "partition")


def link_name(kind: str, src: int, dst: int) -> str:
    """Stable name of a directed link, e.g. ``formation:1>3``; the world is 0."""
    return f"{kind}:{src}>{dst}"


def uniform(seed: int, link: str, seq: int) -> float:
    """A uniform number in [0, 1) that depends only on (seed, link, seq)."""
    h = hashlib.blake2b(digest_size=8, key=struct.pack("<q", seed)[:8])
    h.update(link.encode())
    h.update(struct.pack("<Q", seq & 0xFFFFFFFFFFFFFFFF))
    return struct.unpack("<Q", h.digest())[0] / _SCALE


def fault_key(fault: Fault, occurrence: int = 0) -> str:
    """What a fault's draws are keyed by: its text and how many identical faults
    come before it in the schedule. Not its place in the schedule, so that
    adding another fault changes none of this one's draws."""
    return f"{fault}~{occurrence}"


def fault_uniform(seed: int, link: str, seq: int, key: str, draw: int = 0) -> float:
    """The ``draw``-th uniform number of the fault keyed ``key`` (``fault_key``)
    for message ``seq`` of ``link``: ``uniform`` over the name ``"<link>#<key>/<draw>"``."""
    return uniform(seed, f"{link}#{key}/{draw}", seq)


def whole_ticks(value: float, unit: str, dt_s: float) -> int:
    """A delay in ``"ticks"`` or ``"ms"`` as whole ticks, rounded up (a message
    can only come out at a tick)."""
    ticks = value if unit == "ticks" else value / (1000.0 * dt_s)
    return max(0, math.ceil(ticks - 1e-9))


def faults_on(schedule: Sequence[Fault], link_class: str, robot_id: int) -> tuple[tuple[int, Fault], ...]:
    """The faults of a run's schedule on one directed link, with their index in
    the schedule: ``link_class`` ``"obs"`` (world -> robot), ``"cmd"`` (robot ->
    world) or ``"formation"`` (leader -> follower)."""
    on = link_faults(schedule, link_class, robot_id)
    return tuple((i, f) for i, f in enumerate(schedule) if any(f is g for g in on))


@dataclass(frozen=True)
class _Rule:
    """One fault as the link applies it: its window in ticks and its numbers."""

    index: int
    kind: str
    start: int
    end: int | None  # first tick it no longer applies to; None: to the end
    p: float = 0.0  # drop, duplicate, reorder
    p_bad: float = 0.0  # burst
    p_good: float = 0.0
    loss: float = 1.0
    delay: int = 0  # delay, whole ticks
    jitter: int = 0

    def active(self, tick: int) -> bool:
        return self.start <= tick and (self.end is None or tick < self.end)

    @classmethod
    def of(cls, index: int, fault: Fault, dt_s: float) -> _Rule:
        if fault.kind not in LINK_KINDS:
            raise ValueError(f"fault {index} ({fault}) is not a link fault; link faults: {', '.join(LINK_KINDS)}")
        start, end = fault.start_tick(dt_s), fault.end_tick(dt_s)
        kind = fault.kind
        if kind in ("drop", "duplicate", "reorder"):
            return cls(index, kind, start, end, p=fault.param("p"))
        if kind == "burst":
            return cls(
                index,
                kind,
                start,
                end,
                p_bad=fault.param("p_bad"),
                p_good=fault.param("p_good"),
                loss=fault.param("loss"),
            )
        if kind == "delay":
            unit = "ticks" if fault.has("ticks") else "ms"
            jitter_unit = "ms" if fault.has("jitter_ms") else "ticks"
            return cls(
                index,
                kind,
                start,
                end,
                delay=whole_ticks(fault.param(unit), unit, dt_s),
                jitter=whole_ticks(fault.param(f"jitter_{jitter_unit}"), jitter_unit, dt_s),
            )
        return cls(index, kind, start, end)  # partition


class Link(Generic[T]):
    """Receiver side of one directed link: decides, counts, holds.

    ``faults`` are (index in the run's schedule, fault) pairs (``faults_on``);
    ``dt_s`` turns their times into ticks and is required with faults.
    """

    def __init__(
        self,
        name: str,
        drop_probability: float,
        seed: int,
        faults: Iterable[tuple[int, Fault]] = (),
        dt_s: float | None = None,
    ) -> None:
        self.name = name
        self.seed = seed
        self.drop_probability = probability(f"drop probability of link {name}", drop_probability)
        faults = tuple(faults)
        if faults and dt_s is None:
            raise ValueError(f"link {name}: dt_s is needed to place its faults on ticks")
        dt = positive(f"dt_s of link {name}", dt_s) if dt_s is not None else 0.0
        self.rules = tuple(_Rule.of(i, f, dt) for i, f in faults)
        seen: collections.Counter[str] = collections.Counter()
        self.keys: dict[int, str] = {}  # each rule's draws, by index: keyed by its fault's text
        for i, f in faults:
            self.keys[i] = fault_key(f, seen[str(f)])
            seen[str(f)] += 1
        self.received = 0
        self.dropped = 0
        self.partitioned = 0
        self.delayed = 0
        self.duplicated = 0
        self.reordered = 0
        self.by_fault: dict[int, collections.Counter[str]] = {r.index: collections.Counter() for r in self.rules}
        self._bad: dict[int, bool] = {r.index: False for r in self.rules if r.kind == "burst"}  # Gilbert-Elliott
        self._delayed: list[tuple[int, int, list[T]]] = []  # heap of (release tick, arrival order, copies)
        self._order = 0
        self._reorder_held: list[T] | None = None

    @property
    def fault_ends(self) -> tuple[int, ...]:
        """The ticks at which a fault window of this link ends (sorted; a fault
        to the run's end has none): after one, its counts are final."""
        return tuple(sorted({r.end for r in self.rules if r.end is not None}))

    @property
    def lost(self) -> int:
        """Messages lost on this link so far: dropped or partitioned."""
        return self.dropped + self.partitioned

    @property
    def held(self) -> int:
        """Messages held by the link now (delayed or reordered)."""
        return len(self._delayed) + (self._reorder_held is not None)

    def forget_held(self) -> int:
        """Drop what the link holds (its sender is gone: a restarted agent's
        predecessor); how many messages, counted as lost."""
        n = self.held
        self._delayed.clear()
        self._reorder_held = None
        self.dropped += n
        return n

    def accept(self, seq: int) -> bool:
        """The steady drop alone, for a link without faults: True if message
        ``seq`` gets through; counts either way."""
        if self.rules:
            raise ValueError(f"link {self.name} has faults: hand its messages to deliver(seq, tick, item)")
        self.received += 1
        if self._steady_drop(seq):
            self.dropped += 1
            return False
        return True

    def deliver(self, seq: int, tick: int, item: T) -> list[T]:
        """Message ``seq`` of sim tick ``tick`` arrives: what the receiver gets
        now (see the module's docstring). Counts what happens to it."""
        self.received += 1
        if not self.rules:  # the steady drop alone: nothing is ever held (every tick of a run without faults)
            if self._steady_drop(seq):
                self.dropped += 1
                return []
            return [item]
        out = self.due(tick)
        held, self._reorder_held = self._reorder_held, None
        rules = [r for r in self.rules if r.active(tick)]
        cut = next((r for r in rules if r.kind == "partition"), None)
        # Every burst chain in its window steps at every message, whatever else befalls it.
        burst_loss = [r for r in rules if r.kind == "burst" and self._burst_loses(r, seq)]
        if cut is not None:
            self._count(PARTITIONED, cut)
        elif self._steady_drop(seq):
            self._count(DROPPED)
        elif (dropper := self._dropper(seq, rules, burst_loss)) is not None:
            self._count(DROPPED, dropper)
        else:
            out += self._pass(seq, tick, item, rules)
        if held is not None:
            if cut is not None:
                self._count(PARTITIONED, cut)
            else:
                out += held
        return out

    def _pass(self, seq: int, tick: int, item: T, rules: list[Any]) -> list[T]:
        """A message no rule drops: duplicated, delayed or held for reordering
        as its rules draw (in this order, at every message); what goes out now."""
        copies = [item]
        dup = next((r for r in rules if r.kind == "duplicate" and self._draw(r, seq) < r.p), None)
        if dup is not None:
            self._count(DUPLICATED, dup)
            copies = [item, item]
        delay = 0
        for r in rules:
            if r.kind == "delay" and (d := r.delay + self._jitter(r, seq)) > 0:
                self.by_fault[r.index][DELAYED] += 1
                delay += d
        reorder = next((r for r in rules if r.kind == "reorder" and self._draw(r, seq) < r.p), None)
        if delay > 0:
            self.delayed += 1
            self._order += 1
            heapq.heappush(self._delayed, (tick + delay, self._order, copies))
            return []
        if reorder is not None:
            self._count(REORDERED, reorder)
            self._reorder_held = copies
            return []
        return copies

    def due(self, tick: int) -> list[T]:
        """The delayed messages whose release tick is ``tick`` or earlier, in
        the order of their release ticks (then of their arrival)."""
        out: list[T] = []
        while self._delayed and self._delayed[0][0] <= tick:
            release, _, copies = heapq.heappop(self._delayed)
            cut = next((r for r in self.rules if r.kind == "partition" and r.active(release)), None)
            if cut is not None:
                self._count(PARTITIONED, cut)
            else:
                out += copies
        return out

    def stats(self) -> dict[str, Any]:
        """The counts, for a process's stats: per effect, and per fault index
        (as a string: JSON keys) the messages each fault affected."""
        out: dict[str, Any] = {
            "received": self.received,
            "dropped": self.dropped,
            "partitioned": self.partitioned,
            "delayed": self.delayed,
            "duplicated": self.duplicated,
            "reordered": self.reordered,
            "held": self.held,
        }
        if self.rules:
            out["faults"] = {str(i): dict(c) for i, c in self.by_fault.items() if c}
        return out

    # -- the draws ------------------------------------------------------------------
    def _steady_drop(self, seq: int) -> bool:
        return self.drop_probability > 0.0 and uniform(self.seed, self.name, seq) < self.drop_probability

    def _draw(self, rule: _Rule, seq: int, draw: int = 0) -> float:
        return fault_uniform(self.seed, self.name, seq, self.keys[rule.index], draw)

    def _burst_loses(self, rule: _Rule, seq: int) -> bool:
        """Step the rule's two-state chain (draw 0), then, in the bad state, lose
        the message with probability ``loss`` (draw 1)."""
        u = self._draw(rule, seq)
        bad = not (u < rule.p_good) if self._bad[rule.index] else u < rule.p_bad
        self._bad[rule.index] = bad
        return bad and self._draw(rule, seq, 1) < rule.loss

    def _dropper(self, seq: int, rules: list[_Rule], burst_loss: list[_Rule]) -> _Rule | None:
        """The first fault (in schedule order) that loses message ``seq``."""
        for r in rules:
            if (r.kind == "drop" and self._draw(r, seq) < r.p) or (r.kind == "burst" and r in burst_loss):
                return r
        return None

    def _jitter(self, rule: _Rule, seq: int) -> int:
        """Uniform over 0..jitter whole ticks."""
        return min(rule.jitter, int(self._draw(rule, seq) * (rule.jitter + 1))) if rule.jitter else 0

    def _count(self, effect: str, rule: _Rule | None = None) -> None:
        setattr(self, effect, getattr(self, effect) + 1)
        if rule is not None:
            self.by_fault[rule.index][effect] += 1
