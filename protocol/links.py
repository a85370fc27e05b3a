"""Directed links and their faults, applied by our own link layer.

Every directed link (world -> agent observations, agent -> world commands,
leader -> follower formation codes) has a drop probability. Whether message
``seq`` on a link is dropped is a pure function of (seed, link, seq), so the
same run drops the same messages however the machine is loaded.

Drops are applied by the receiver: the message crosses Zenoh (so a lockstep
tick still completes) and the receiving link layer discards it as lost. The
receiver counts it, as it would count a gap in the sender's sequence numbers.
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass

from formation_swarm.checks import probability

_SCALE = float(2**64)


def link_name(kind: str, src: int, dst: int) -> str:
    """Stable name of a directed link, e.g. ``formation:1>3``; the world is 0."""
    return f"{kind}:{src}>{dst}"


def uniform(seed: int, link: str, seq: int) -> float:
    """A uniform number in [0, 1) that depends only on (seed, link, seq)."""
    h = hashlib.blake2b(digest_size=8, key=struct.pack("<q", seed)[:8])
    h.update(link.encode())
    h.update(struct.pack("<Q", seq & 0xFFFFFFFFFFFFFFFF))
    return struct.unpack("<Q", h.digest())[0] / _SCALE


@dataclass
class Link:
    """Receiver side of one directed link: drops and counts."""

    name: str
    drop_probability: float
    seed: int
    received: int = 0
    dropped: int = 0

    def __post_init__(self) -> None:
        self.drop_probability = probability(f"drop probability of link {self.name}", self.drop_probability)

    def accept(self, seq: int) -> bool:
        """True if message ``seq`` gets through; counts either way."""
        self.received += 1
        if self.drop_probability > 0.0 and uniform(self.seed, self.name, seq) < self.drop_probability:
            self.dropped += 1
            return False
        return True
