"""What an agent accepts of what reaches its inbox, beyond a message's schema.

The decoder (protocol.codec) proves a message well formed and the key proves
who claims to have sent it; these checks make sure it could be true:

- an observation is newer than the last one taken (a replayed or reordered one
  is dropped), and every reading in it is one the camera could make: a robot
  of the run, a distance within the camera's range plus its noise, angles
  wrapped to [-pi, pi]; obstacles within the leader's sensing range;
- a formation code is newer than the last one taken from the leader, by
  (tick, seq): a later tick, or the same tick and a higher seq. A restarted
  leader counts its messages from 1 again but stamps the current tick, so it
  is heard; a replay (an older tick, or the same tick and seq) is not. And a
  code is not stamped far past the agent's own clock (such a code would
  otherwise wait in the queue, or hold back the real ones).

The agent's link layer (protocol.links) sits between these checks and the
controller: what arrives is checked first, then handed to the link layer, and
what the link layer hands over (the same message, a duplicate of it, one it
held back) is checked again for order alone: an observation whose tick, or
a code whose (tick, seq), is not above the last one handed over and taken is
"replayed or reordered". That is how a duplicated or reordered message ends.

Each check returns the reason of a rejection (counted by the agent) or None.
:class:`ObservationInbox` runs them on a role's observations and keeps the
newest for its answer. No Zenoh here: the agent process feeds the role
decoded messages.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.links import Link
from formation_swarm.protocol.messages import WORLD_ID, FormationCode, Observation

# Beyond the camera's range a reading is noise: allow 8 sigma of it (a false
# rejection about once in 1e15 readings) and nothing more.
RHO_SIGMAS = 8.0
ANGLE_LIMIT_RAD = math.pi + 1e-9
# How far past the agent's own last observation a code may be stamped: the
# leader may be ahead of a slow follower in real time (ticks of 5 s of sim).
CODE_AHEAD_S = 5.0
# The reasons of the order checks' rejections, as the agent counts them.
REPLAYED = "replayed or reordered"  # not newer than the last one taken (or handed over)
TICK_AHEAD = "tick ahead of the world"  # a code stamped past the agent's clock by more than CODE_AHEAD_S


class InboxChecks:
    def __init__(
        self,
        robots: Iterable[int],
        camera_range_m: float,
        sigma_rho_m: float,
        sensing_range_m: float,
        dt_s: float,
    ) -> None:
        self.robots = frozenset(robots)
        self.max_rho_m = camera_range_m + RHO_SIGMAS * sigma_rho_m
        self.sensing_range_m = sensing_range_m
        self.code_ahead_ticks = max(2, math.ceil(CODE_AHEAD_S / dt_s))
        self.last_tick = -1  # of the last observation taken
        self.last_code = (-1, -1)  # (tick, seq) of the last formation code taken
        self.last_reading_tick = -1  # of the last observation the link layer handed over and taken
        self.last_handed_code = (-1, -1)  # (tick, seq) of the last code the link layer handed over and taken

    def observation(self, obs: Observation) -> str | None:
        if obs.tick <= self.last_tick:
            return REPLAYED
        if not self._readings_plausible(obs.readings) and (why := self._reading_rejected(obs.readings)) is not None:
            return why
        for dist, bearing, radius in obs.obstacles:
            if not (radius > 0.0 and dist >= 0.0 and dist - radius <= self.sensing_range_m + 1e-9):
                return "obstacle out of bounds"
            if abs(bearing) > ANGLE_LIMIT_RAD:
                return "obstacle out of bounds"
        self.last_tick = obs.tick
        return None

    def _readings_plausible(self, readings: tuple[tuple[int, float, float, float], ...]) -> bool:
        """Whether every reading passes (the common case, tested a column at a
        time in C: a camera sees a dozen markers in a long line)."""
        if not readings:
            return True
        rids, rhos, phis, betas = zip(*readings, strict=True)
        return (
            self.robots.issuperset(rids)
            and min(rhos) >= 0.0
            and max(rhos) <= self.max_rho_m
            and max(map(abs, phis)) <= ANGLE_LIMIT_RAD
            and max(map(abs, betas)) <= ANGLE_LIMIT_RAD
        )

    def _reading_rejected(self, readings: tuple[tuple[int, float, float, float], ...]) -> str | None:
        """The reason of the first reading that fails, in order."""
        for rid, rho, phi, beta in readings:
            if rid not in self.robots:
                return "unknown robot"
            if not (0.0 <= rho <= self.max_rho_m and abs(phi) <= ANGLE_LIMIT_RAD and abs(beta) <= ANGLE_LIMIT_RAD):
                return "reading out of bounds"
        return None

    def code(self, fc: FormationCode) -> str | None:
        if (fc.tick, fc.seq) <= self.last_code:
            return REPLAYED
        if fc.tick > self.last_tick + self.code_ahead_ticks:
            return TICK_AHEAD
        self.last_code = (fc.tick, fc.seq)
        return None

    def reading(self, obs: Observation) -> str | None:
        """An observation the link layer hands over (already taken on arrival)."""
        if obs.tick <= self.last_reading_tick:
            return REPLAYED
        self.last_reading_tick = obs.tick
        return None

    def handed_code(self, fc: FormationCode) -> str | None:
        """A formation code the link layer hands over (already taken on arrival)."""
        if (fc.tick, fc.seq) <= self.last_handed_code:
            return REPLAYED
        self.last_handed_code = (fc.tick, fc.seq)
        return None


class ObservationInbox:
    """The observations a role takes, until it answers.

    Each is checked on arrival, passed through the receiving end of the
    observation link, and what the link hands over is checked again for
    order. Only the newest observation taken is answered (after a stall the
    older ones are stale: ``superseded`` counts them), with the newest
    reading the link handed over since the last answer (None: lost, held,
    or only replays)."""

    def __init__(self, link: Link[Observation], checks: InboxChecks, rejections: Rejections) -> None:
        self.link = link
        self.checks = checks
        self.rejections = rejections
        self.superseded = 0
        self._newest: Observation | None = None
        self._reading: Observation | None = None

    def take(self, obs: Observation) -> bool:
        """Whether ``obs`` was taken (else its rejection is counted)."""
        if obs.sender != WORLD_ID:
            self.rejections.reject("sender mismatch")
            return False
        if (why := self.checks.observation(obs)) is not None:
            self.rejections.reject(why)
            return False
        for got in self.link.deliver(obs.seq, obs.tick, obs):
            if (why := self.checks.reading(got)) is not None:
                self.rejections.reject(why)
            else:
                self._reading = got
        self.superseded += self._newest is not None
        self._newest = obs
        return True

    def pop(self) -> tuple[Observation, Observation | None] | None:
        """The observation to answer and its reading; None if none was taken since the last."""
        if self._newest is None:
            return None
        got = (self._newest, self._reading)
        self._newest = self._reading = None
        return got
