"""The leader's role: its observations in, its command and formation code out.

Each answered tick it hands its policy (agents.leader_policy; the paper's
PathLeader) what its sensors gave it, flies the formation the policy names,
and, when the policy says so, sends that code to its followers: one put for
all of them, each follower's end of its one-way link applying that link's
faults. The code goes out before the command, so that in lockstep every
follower holds it before the world publishes the next tick.
"""

from __future__ import annotations

from typing import Any

from formation_swarm.agents.leader_policy import LeaderPolicy, LeaderSensing
from formation_swarm.agents.role_base import Answer, RoleBase, RoleSetup
from formation_swarm.protocol.messages import Command, FormationCode
from formation_swarm.world.kinematics import Pose


class LeaderRole(RoleBase):
    NAME = "leader"
    SENDS_CODES = True

    def __init__(self, setup: RoleSetup, policy: LeaderPolicy) -> None:
        super().__init__(setup)
        self.policy = policy

    def answer(self) -> Answer | None:
        got = self.inbox.pop()
        if got is None:
            return None
        obs, reading = got
        sensed = None if reading is None else LeaderSensing(pose=Pose(*reading.pose), obstacles=reading.obstacles)
        self.step_times.start(obs.tick)
        try:
            move = self.policy.step(sensed)
        finally:
            self.step_times.stop()
        self.code = move.formation
        code = None
        if move.send_code:
            code = FormationCode(sender=self.robot_id, seq=self._next_seq(), tick=obs.tick, code=self.code)
        command = Command(
            sender=self.robot_id,
            seq=self._next_seq(),
            tick=obs.tick,
            left_mps=move.left_mps,
            right_mps=move.right_mps,
            formation=self.code,
            done=move.finished,
        )
        self._answered(obs.tick)
        return Answer(command=command, code=code)

    def stats(self) -> dict[str, Any]:
        # A follower's counters, none of which the leader has.
        follower = {
            "ekf_resets": 0,
            "held_ticks": 0,
            "holds": [],
            "waited_ticks": 0,
            "formation_changes": [],
            "controller_failure": None,
        }
        return {**super().stats(), **follower}
