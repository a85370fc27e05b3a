"""A follower controller and a leader's policy with the optional hooks
``reset()`` and ``close()`` (agents.hooks), for tests: the paper's law and
path behind them. Each instance counts its calls (``calls``; every instance
made in this process is in ``MADE``); given ``log``, a file, it also writes
a line per hook call there (a run's agents are other processes);
``raise_in`` names a hook that raises.

A run names them as ``tests.helpers.hooked:Follower`` and
``tests.helpers.hooked:Leader``.
"""

from __future__ import annotations

import collections
from pathlib import Path

from formation_swarm.agents.controller import ControllerSetup, FollowerInput, FollowerOutput
from formation_swarm.agents.follower import FuzzyController
from formation_swarm.agents.leader_policy import LeaderMove, LeaderSensing, LeaderSetup, PathLeader

MODULE = "tests.helpers.hooked"
MADE: list[Follower | Leader] = []
PARAMS = {"log": "", "raise_in": ""}  # raise_in: "reset", "close" or "step"


class _Hooks:
    def _hooked(self, robot_id: int, params: object) -> None:
        self.robot_id = robot_id
        self.log = str(params["log"])  # type: ignore[index]
        self.raise_in = str(params["raise_in"])  # type: ignore[index]
        self.calls: collections.Counter[str] = collections.Counter()
        MADE.append(self)  # type: ignore[arg-type]

    def _call(self, hook: str) -> None:
        self.calls[hook] += 1
        if self.log and hook != "step":
            with Path(self.log).open("a") as f:
                f.write(f"{hook} {self.robot_id}\n")
        if hook == self.raise_in:
            raise RuntimeError(f"{hook} failing on purpose")

    def reset(self) -> None:
        self._call("reset")

    def close(self) -> None:
        self._call("close")


class Follower(_Hooks):
    """The paper's follower, its hooks counted."""

    PARAMS = PARAMS

    def __init__(self, setup: ControllerSetup) -> None:
        self.inner = FuzzyController(setup)
        self._hooked(setup.robot_id, setup.law_params)

    def step(self, inp: FollowerInput) -> FollowerOutput:
        self._call("step")
        return self.inner.step(inp)


class Leader(PathLeader, _Hooks):
    """The paper's leader, its hooks counted."""

    PARAMS = PARAMS

    def __init__(self, setup: LeaderSetup) -> None:
        super().__init__(setup)
        self._hooked(setup.robot_id, setup.policy_params)

    def step(self, sensed: LeaderSensing | None) -> LeaderMove:
        self._call("step")
        return super().step(sensed)
