"""The leader's role: its observations in, its command and formation code out.

Each answered tick it hands its policy (agents.leader_policy; the paper's
PathLeader) what its sensors gave it, flies the formation the policy names,
and, when the policy says so, sends that code to its followers: one put for
all of them, each follower's end of its one-way link applying that link's
faults. The code goes out before the command, so that in lockstep every
follower holds it before the world publishes the next tick.

A policy that raises, or answers wheel speeds that are not finite numbers
or a formation that is not one of the run's codes, has failed, as a
follower's controller does (agents.follower_role): from that tick on the
leader answers with zero speeds, sends no code and never calls it again;
the failure is in the stats (``controller_failure``) and its traceback in
``notes``. Its ``close()`` (agents.hooks) is called once when the agent stops.
"""

from __future__ import annotations

import math
from typing import Any

from formation_swarm.agents import hooks
from formation_swarm.agents.leader_policy import LeaderMove, LeaderPolicy, LeaderSensing
from formation_swarm.agents.role_base import Answer, RoleBase, RoleSetup
from formation_swarm.protocol.messages import Command, FormationCode
from formation_swarm.world.kinematics import Pose


class LeaderRole(RoleBase):
    NAME = "leader"
    SENDS_CODES = True

    def __init__(self, setup: RoleSetup, policy: LeaderPolicy, law: str | None = None) -> None:
        super().__init__(setup)
        self.policy = policy
        self._hooked(policy, law)

    def answer(self) -> Answer | None:
        got = self.inbox.pop()
        if got is None:
            return None
        obs, reading = got
        sensed = None if reading is None else LeaderSensing(pose=Pose(*reading.pose), obstacles=reading.obstacles)
        move = self._step(obs.tick, sensed) if self.failure is None else None
        if move is None:  # failed, now or before: stopped, its followers on the last code they took
            move = LeaderMove(left_mps=0.0, right_mps=0.0, formation=self.code, send_code=False, finished=False)
        self.code = move.formation
        code = None
        if move.send_code:
            code = FormationCode(sender=self.robot_id, seq=self._next_seq(), tick=obs.tick, code=self.code)
        command = Command(
            sender=self.robot_id,
            seq=self._next_seq(),
            tick=obs.tick,
            left_mps=float(move.left_mps),
            right_mps=float(move.right_mps),
            formation=self.code,
            done=bool(move.finished),
        )
        self._answered(obs.tick)
        return Answer(command=command, code=code)

    def _step(self, tick: int, sensed: LeaderSensing | None) -> LeaderMove | None:
        """The policy's move, timed and checked; None when it fails (recorded)."""
        self.step_times.start(tick)
        try:
            move = self.policy.step(sensed)
            _check(move, len(self.formations))
        except Exception as exc:  # noqa: BLE001 - whatever the policy does wrong stops the leader only
            self.failure, note = hooks.failure(tick, exc, self.law, self.robot_id)
            self.notes.append(note)
            return None
        finally:
            if (note := self.step_times.first_slow(f"policy {self.law}", tick)) is not None:
                self.notes.append(note)
        return move

    def stats(self) -> dict[str, Any]:
        # A follower's counters, none of which the leader has.
        follower = {
            "ekf_resets": 0,
            "held_ticks": 0,
            "holds": [],
            "waited_ticks": 0,
            "formation_changes": [],
            "controller_failure": self.failure,
        }
        return {**super().stats(), **follower}


def _check(move: Any, codes: int) -> None:
    """A move the leader can fly: finite wheel speeds, one of the run's ``codes`` formations."""
    if not isinstance(move, LeaderMove):
        raise TypeError(f"a policy's step must return a LeaderMove, got {type(move).__name__}")
    if not (math.isfinite(move.left_mps) and math.isfinite(move.right_mps)):
        raise ValueError(
            f"wheel speeds must be finite numbers, got left_mps={move.left_mps!r}, right_mps={move.right_mps!r}"
        )
    if isinstance(move.formation, bool) or not isinstance(move.formation, int) or not 0 <= move.formation < codes:
        raise ValueError(f"formation must be a code in [0, {codes - 1}], got {move.formation!r}")
