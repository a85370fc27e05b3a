"""Follower controllers of a user's kind (docs/controllers.md), for tests: one
that flies the paper's law with parameters and values of its own, ones that
fail at a given step, and classes that are not controllers.

A run names them as ``tests.helpers.controllers:NAME``: the agents import
them from the test session's Python path (the repository's root is on it,
and forked agents inherit it from the launcher).
"""

from __future__ import annotations

import math

from formation_swarm.agents.controller import ControllerSetup, FollowerInput, FollowerOutput
from formation_swarm.agents.follower import FuzzyController

LAW = "tests.helpers.controllers"


class Paper:
    """The paper's controller behind a user's class: its parameters declared,
    a value of its own in the telemetry, and a failure at a chosen step."""

    PARAMS = {"fail_at_step": -1, "nan_at_step": -1, "scale": 1.0, "note": "none", "loud": False}

    def __init__(self, setup: ControllerSetup) -> None:
        self.inner = FuzzyController.from_setup(setup)
        self.params = setup.law_params
        self.steps = 0

    def step(self, inp: FollowerInput) -> FollowerOutput:
        step = self.steps
        self.steps += 1
        if step == self.params["fail_at_step"]:
            raise RuntimeError(f"failing on purpose at step {step}")
        out = self.inner.step(inp)
        left, right = out.left_mps * self.params["scale"], out.right_mps * self.params["scale"]
        if step == self.params["nan_at_step"]:
            left = math.nan
        telemetry = {**out.telemetry, "steps": float(self.steps), "scale": self.params["scale"]}
        return FollowerOutput(left_mps=left, right_mps=right, telemetry=telemetry)

    def prepare(self) -> None:
        self.inner.prepare()


class NoStep:
    """A class without ``step``: not a follower controller."""

    def __init__(self, setup: ControllerSetup) -> None:
        self.setup = setup

    def decide(self, inp: FollowerInput) -> FollowerOutput:
        return FollowerOutput(left_mps=0.0, right_mps=0.0)


class BadInit:
    """A controller whose constructor raises: it fails at its first tick."""

    def __init__(self, setup: ControllerSetup) -> None:
        raise ValueError(f"robot {setup.robot_id} cannot be built")

    def step(self, inp: FollowerInput) -> FollowerOutput:
        return FollowerOutput(left_mps=0.0, right_mps=0.0)


class Chatty:
    """Stands still and sends more values of its own than the wire takes, one
    of them badly named and one NaN."""

    def __init__(self, setup: ControllerSetup) -> None:
        self.setup = setup

    def step(self, inp: FollowerInput) -> FollowerOutput:
        values = {f"v{i}": float(i) for i in range(20)}
        values.update({"bad name": 1.0, "v0": math.nan, "rho_m": 0.5})
        return FollowerOutput(left_mps=0.0, right_mps=0.0, telemetry=values)
