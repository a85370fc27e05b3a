"""An agent's wire: what arrives, decoded and handed to its role; what the
role answers, encoded and published. No Zenoh here: the process declares
the subscribers and publishers (nodes.agent.main) and a test passes stand-ins.
"""

from __future__ import annotations

import math
from typing import Any

from formation_swarm.agents.role_base import Answer, RoleBase
from formation_swarm.protocol.batch import BatchPublisher
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import FormationCode, Observation
from formation_swarm.runtime.spool import SpoolWriter

# Telemetry is for the logger only. Up to TELEMETRY_BATCH_ABOVE robots each
# tick's goes out at once (protocol.batch's 20 ms window); beyond, a follower
# sends every TELEMETRY_TICKS ticks, on a tick set by its id so that the
# followers' sends spread over the ticks: every tick's telemetry is still sent,
# in a fifth of the puts (each one routed by the router and taken by the logger).
TELEMETRY_BATCH_ABOVE = 25
TELEMETRY_TICKS = 5
TELEMETRY_WINDOW_S = 0.02


class Router:
    """Hands what reaches a robot's inbox to its role, decoded. Anything else
    is counted in the role's rejections and dropped: a key that is not this
    robot's, a kind the role does not take, a payload that does not decode."""

    def __init__(self, keys: Keys, role: RoleBase, spool: SpoolWriter | None = None) -> None:
        self.keys = keys
        self.role = role
        self.spool = spool  # every message taken, for the wire recording (None: not kept)
        # Compared with every inbox message's key: built once.
        self.codes_key = keys.codes
        self.obs_key = keys.obs(role.robot_id)

    def take(self, key: str, payload: bytes) -> None:
        role, rejections, spool = self.role, self.role.rejections, self.spool
        if key == self.obs_key:  # every tick's: its key need not be taken apart
            obs = rejections.decode(Observation, payload)
            if spool is not None:  # as decoded: its tick and seq, never a second decode
                spool.add(key, payload, *((None, None) if obs is None else (obs.tick, obs.seq)))
            if obs is not None:
                role.take_observation(obs)
            return
        if key == self.codes_key:
            fc = rejections.decode(FormationCode, payload) if role.TAKES_CODES else None
            if spool is not None:
                spool.add(key, payload, *((None, None) if fc is None else (fc.tick, fc.seq)))
            if not role.TAKES_CODES:
                rejections.reject("unexpected key")
            elif fc is not None:
                role.take_code(fc)
            return
        if spool is not None:  # refused below, but it reached the inbox: kept as it came
            spool.add(key, payload)
        rk = self.keys.parse_robot(key)  # another of this robot's keys (not its obs), or none of it
        if rk is None or rk.robot_id != role.robot_id:
            rejections.reject("unknown key")
        else:
            rejections.reject("unexpected key")


class Outbox:
    """Publishes a role's answers: the code, then the command, then the
    telemetry (batched: ``TELEMETRY_*``)."""

    def __init__(self, robot_id: int, robots: int, cmd_pub: Any, tel_pub: Any, code_pub: Any = None) -> None:
        self.robot_id = robot_id
        self.tel_every = 1 if robots <= TELEMETRY_BATCH_ABOVE else TELEMETRY_TICKS  # ticks per telemetry put
        self.cmd = cmd_pub
        # By wall time (every tick at 20 Hz), or beyond TELEMETRY_BATCH_ABOVE robots flushed by tick (send).
        self.tel = BatchPublisher(tel_pub, window_s=TELEMETRY_WINDOW_S if self.tel_every == 1 else math.inf)
        self.code = code_pub

    def send(self, answer: Answer) -> None:
        if answer.code is not None and self.code is not None:
            self.code.put(answer.code.to_bytes())
        self.cmd.put(answer.command.to_bytes())
        tel = answer.telemetry
        if tel is not None:
            self.tel.put(tel.to_bytes())
            if self.tel_every > 1 and (tel.tick + self.robot_id) % self.tel_every == 0:
                self.tel.flush()

    def close(self) -> None:
        """The telemetry's last batch and its end-of-stream mark (the logger waits for it)."""
        self.tel.close()
