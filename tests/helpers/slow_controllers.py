"""Follower controllers that take too long, for tests: one whose ``step``
sleeps from a chosen call on, one that spins for ever there. Each flies the
paper's law until then.

A run names them as ``tests.helpers.slow_controllers:NAME`` (the agents
import them from the launcher's Python path, as tests.helpers.controllers).
"""

from __future__ import annotations

import time

from formation_swarm import ControllerSetup, FollowerInput, FollowerOutput
from formation_swarm.agents.follower import FuzzyController

LAW = "tests.helpers.slow_controllers"


class Slow:
    """Sleeps ``sleep_s`` in every ``step`` from its call ``from_step`` (0-based) on."""

    PARAMS = {"from_step": 20, "sleep_s": 2.5}

    def __init__(self, setup: ControllerSetup) -> None:
        self.inner = FuzzyController(setup)
        self.params = setup.law_params
        self.steps = 0

    def step(self, inp: FollowerInput) -> FollowerOutput:
        if self.steps >= self.params["from_step"]:
            time.sleep(self.params["sleep_s"])
        self.steps += 1
        return self.inner.step(inp)

    def prepare(self) -> None:
        self.inner.prepare()


class Hung:
    """Spins for ever (``while True: pass``) in its ``step`` call ``from_step`` (0-based)."""

    PARAMS = {"from_step": 20}

    def __init__(self, setup: ControllerSetup) -> None:
        self.inner = FuzzyController(setup)
        self.params = setup.law_params
        self.steps = 0

    def step(self, inp: FollowerInput) -> FollowerOutput:
        if self.steps >= self.params["from_step"]:
            while True:
                pass
        self.steps += 1
        return self.inner.step(inp)

    def prepare(self) -> None:
        self.inner.prepare()
