"""A follower law for the replay's tests: the paper's, changed at one step.

``tests.helpers.replay_laws:Planted`` flies the paper's controller and adds
``bump_mps`` to its left wheel at step ``at_step`` only (a step is a tick the
follower answered), so ``swarm replay --set controller.law=...`` must name
that step's tick as the first that differs.
"""

from __future__ import annotations

import dataclasses

from formation_swarm import ControllerSetup, FollowerInput, FollowerOutput
from formation_swarm.agents.follower import FuzzyController


class Planted:
    """The paper's law with one step changed (``at_step``, ``bump_mps``)."""

    PARAMS = {"at_step": 30, "bump_mps": 0.001}

    def __init__(self, setup: ControllerSetup) -> None:
        self.inner = FuzzyController(setup)
        self.at_step = int(setup.law_params["at_step"])
        self.bump_mps = float(setup.law_params["bump_mps"])
        self.steps = 0

    def step(self, inp: FollowerInput) -> FollowerOutput:
        out = self.inner.step(inp)
        step, self.steps = self.steps, self.steps + 1
        if step == self.at_step:
            return dataclasses.replace(out, left_mps=out.left_mps + self.bump_mps)
        return out

    def prepare(self) -> None:
        self.inner.prepare()
