"""The world's side of the wire it sends on, and who of the run is there:
:class:`Outbox` (each robot's observations, the truth, the status, the
fault calls, every robot's observations again for a ROS 2 bridge) and
:class:`Peers` (from the liveliness tokens)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import zenoh

from formation_swarm.protocol import sightings as sightings_mod
from formation_swarm.protocol.batch import BatchPublisher
from formation_swarm.protocol.keys import Keys

TRUTH_WINDOW_S = 0.02  # the truth's batches: every tick's at 20 Hz, many ticks a put in a fast lockstep run


@dataclass
class Peers:
    """Who of the run is there, from the liveliness tokens."""

    agents_seen: set[int] = field(default_factory=set)
    logger_seen: bool = False
    executor_seen: bool = False
    bridge_seen: bool = False  # the ROS 2 bridge (--expect-bridge)
    present: set[str] = field(default_factory=set)  # alive keys of the agents and the logger
    # When the logger's token went before "done": the tick its recording is cut at.
    logger_lost: dict[str, Any] | None = None


@dataclass
class Outbox:
    """The world's publishers: each robot's observations, the truth, the status, the fault calls."""

    obs: dict[int, zenoh.Publisher]
    truth: BatchPublisher
    status: zenoh.Publisher
    faults: zenoh.Publisher | None  # only with an executor of the calls (--process-faults)
    matching: list[Any] = field(default_factory=list)
    sightings: zenoh.Publisher | None = None  # only with a ROS 2 bridge: every robot's observations

    @classmethod
    def declare(  # noqa: PLR0913 -- the publishers' settings, each once
        cls,
        sess: zenoh.Session,
        keys: Keys,
        robots: tuple[int, ...],
        truth_cc: zenoh.CongestionControl,
        *,
        calls: bool,
        truth_window_s: float = TRUTH_WINDOW_S,
        sightings: bool = False,
    ) -> Outbox:
        block = zenoh.CongestionControl.BLOCK  # Zenoh never drops an observation; our link layer may
        truth = sess.declare_publisher(keys.truth, congestion_control=truth_cc)
        return cls(
            obs={rid: sess.declare_publisher(keys.obs(rid), congestion_control=block) for rid in robots},
            truth=BatchPublisher(truth, window_s=truth_window_s),
            status=sess.declare_publisher(keys.status),
            faults=sess.declare_publisher(keys.faults, congestion_control=block) if calls else None,
            # As the truth: what the bridge shows, not what anyone answers. The bridge does not subscribe
            # each robot's obs instead: that subscription is how the world knows its agent is there.
            sightings=sess.declare_publisher(keys.sightings, congestion_control=truth_cc) if sightings else None,
        )

    def sighted(self, encoded: list[tuple[int, bytes]]) -> None:
        """The tick's observations (robot id, bytes) once more, gathered for the ROS 2 bridge (protocol.sightings)."""
        if self.sightings is not None:
            for payload in sightings_mod.pack(encoded):
                self.sightings.put(payload)

    def listen(self, wake: Callable[[], None]) -> None:
        """A matching change wakes the loop: before tick 0, and when a fresh agent subscribes mid-run."""
        self.matching = [p.declare_matching_listener(lambda _status: wake()) for p in self.obs.values()]

    def hears(self, rid: int) -> bool:
        """Whether robot ``rid``'s observations have a subscriber."""
        return self.obs[rid].matching_status.matching
