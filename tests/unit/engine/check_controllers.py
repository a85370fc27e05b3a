"""Follower controllers that engine.check refuses, one fault each, named by
``tests.unit.engine.check_controllers:NAME``."""

from __future__ import annotations

import math
import random

import numpy as np

from formation_swarm import ControllerSetup, FollowerInput, FollowerOutput

LAW = "tests.unit.engine.check_controllers"


class Still:
    """Stands still: passes every check."""

    PARAMS = {"speed_mps": 0.0}

    def __init__(self, setup: ControllerSetup) -> None:
        self.speed_mps = setup.law_params["speed_mps"]

    def step(self, inp: FollowerInput) -> FollowerOutput:
        return FollowerOutput(left_mps=self.speed_mps, right_mps=self.speed_mps)


class Nan(Still):
    def step(self, inp: FollowerInput) -> FollowerOutput:
        return FollowerOutput(left_mps=math.nan, right_mps=0.0)


class PyRandom(Still):
    def step(self, inp: FollowerInput) -> FollowerOutput:
        return FollowerOutput(left_mps=random.random(), right_mps=0.0)


class NpRandom(Still):
    def step(self, inp: FollowerInput) -> FollowerOutput:
        return FollowerOutput(left_mps=float(np.random.rand()), right_mps=0.0)


class Raises(Still):
    """Raises at its fifth step, whatever it is fed."""

    def __init__(self, setup: ControllerSetup) -> None:
        super().__init__(setup)
        self.steps = 0

    def step(self, inp: FollowerInput) -> FollowerOutput:
        self.steps += 1
        if self.steps == 5:
            raise RuntimeError("failing on purpose")
        return super().step(inp)


class Pair(Still):
    def step(self, inp: FollowerInput) -> tuple[float, float]:  # type: ignore[override]
        return (0.0, 0.0)


class Blind(Still):
    """Reads the reading without asking whether there is one."""

    def step(self, inp: FollowerInput) -> FollowerOutput:
        speed = 0.1 * inp.reading.rho_m  # type: ignore[union-attr]
        return FollowerOutput(left_mps=speed, right_mps=speed)


class OneTick(Still):
    """Refuses more than one tick a step."""

    def step(self, inp: FollowerInput) -> FollowerOutput:
        if inp.ticks != 1:
            raise ValueError(f"ticks={inp.ticks}")
        return super().step(inp)


class Counts(Still):
    """Its speed grows with its steps, and its reset() forgets to start over;
    its close() raises."""

    def __init__(self, setup: ControllerSetup) -> None:
        super().__init__(setup)
        self.steps = 0

    def reset(self) -> None:
        pass

    def step(self, inp: FollowerInput) -> FollowerOutput:
        self.steps += 1
        return FollowerOutput(left_mps=0.001 * self.steps, right_mps=0.0)

    def close(self) -> None:
        raise OSError("no such device")
