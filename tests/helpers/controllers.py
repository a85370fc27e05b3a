"""Follower controllers of a user's kind (docs/controllers.md), for tests: one
that flies the paper's law with parameters and values of its own, ones that
fail at a given step, and classes that are not controllers. And ByHand: a
built-in law driven by hand, without a role.

A run names them as ``tests.helpers.controllers:NAME``: the agents import
them from the test session's Python path (the repository's root is on it,
and forked agents inherit it from the launcher).
"""

from __future__ import annotations

import dataclasses
import math

from formation_swarm import (
    ControllerSetup,
    FollowerInput,
    FollowerOutput,
    FollowerParams,
    MarkerReading,
    Point,
    Slot,
)
from formation_swarm.agents.follower import FuzzyController, law_class
from formation_swarm.agents.tracking import TrackingController

LAW = "tests.helpers.controllers"


class Paper:
    """The paper's controller behind a user's class: its parameters declared,
    a value of its own in the telemetry, and a failure at a chosen step."""

    PARAMS = {"fail_at_step": -1, "nan_at_step": -1, "scale": 1.0, "note": "none", "loud": False}

    def __init__(self, setup: ControllerSetup) -> None:
        self.inner = FuzzyController(setup)
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
        values = {**out.values, "steps": float(self.steps), "scale": self.params["scale"]}
        return dataclasses.replace(out, left_mps=left, right_mps=right, values=values)

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
        return FollowerOutput(left_mps=0.0, right_mps=0.0, values=values)


Reading = tuple[float, float, float]  # rho_m, phi_rad, beta_rad


class ByHand:
    """A built-in law driven by hand as a follower's role drives it: a reading
    (rho_m, phi_rad, beta_rad) or None in, its FollowerOutput out; the slot
    set by calls, each change handed over with the next step."""

    def __init__(self, params: FollowerParams, offset: tuple[float, float], reference: int = 1) -> None:
        self.slot = Slot(reference, Point(float(offset[0]), float(offset[1])))
        setup = ControllerSetup(robot_id=2, params=params, slot=self.slot, max_wheel_mps=3.0)
        self.law: TrackingController = law_class(params.law)(setup)
        self._moved = self._new_reference = False

    def step(self, reading: Reading | None, ticks: int = 1) -> FollowerOutput:
        marker = None if reading is None else MarkerReading(rho_m=reading[0], phi_rad=reading[1], beta_rad=reading[2])
        inp = FollowerInput(
            reading=marker,
            slot=self.slot,
            slot_moved=self._moved,
            new_reference=self._new_reference,
            ticks=ticks,
            dt_s=ticks * self.law.p.dt_s,
        )
        self._moved = self._new_reference = False
        return self.law.step(inp)

    def move_slot(self, offset: tuple[float, float]) -> None:
        """A new formation's slot on the same reference (a change when the offset differs)."""
        new = Point(float(offset[0]), float(offset[1]))
        self._moved |= new != self.slot.offset
        self.slot = Slot(self.slot.reference, new)

    def new_reference(self, reference: int) -> None:
        self._new_reference = True
        self.slot = Slot(reference, self.slot.offset)

    def prepare(self) -> None:
        self.law.prepare()
