"""A follower's control law: the one the scenario names (``controller.law``).

``make_controller`` builds it for a follower's role (agents.follower_role)
from a ControllerSetup; it is the one place a law's name becomes a class
of agents.controller's API. ``Follower`` is the same controller driven by
hand, with raw readings and formation slots, without a role: the
one-process replays (tests.helpers.replica, formation_swarm.studies.sim)
and the benchmarks use it.

FollowerParams (agents.params), Decision (agents.tracking) and both
controllers are importable from here too: one import for a follower's law.
"""

from __future__ import annotations

from formation_swarm.agents.controller import ControllerSetup, FollowerController
from formation_swarm.agents.fuzzy_controller import FuzzyController, change_over
from formation_swarm.agents.geometry import Point
from formation_swarm.agents.lpsi_controller import LpsiController
from formation_swarm.agents.params import DRHO_AT_SIGN_CHANGE, LAWS, FollowerParams
from formation_swarm.agents.tracking import Decision, Reading, TrackingController

__all__ = [
    "BUILT_IN",
    "DRHO_AT_SIGN_CHANGE",
    "LAWS",
    "Decision",
    "Follower",
    "FollowerParams",
    "FuzzyController",
    "LpsiController",
    "change_over",
    "make_controller",
]

# One class per name of agents.params.LAWS.
BUILT_IN: dict[str, type[TrackingController]] = {"fuzzy": FuzzyController, "lpsi": LpsiController}


def make_controller(setup: ControllerSetup) -> FollowerController:
    """The controller of the law ``setup.params.law`` names."""
    return BUILT_IN[setup.params.law].from_setup(setup)


class Follower:
    """One follower's controller (``params.law``) driven by hand: a reading
    (rho_r, phi, beta) or None in, a Decision out; the slot set by calls."""

    def __init__(self, params: FollowerParams, offset: Point) -> None:
        self.law = BUILT_IN[params.law](params, offset)

    def step(self, reading: Reading | None, ticks: int = 1) -> Decision:
        return self.law.decide(reading, ticks)

    def set_offset(self, offset: Point) -> None:
        self.law.set_offset(offset)

    def new_reference(self) -> None:
        self.law.new_reference()

    def prepare(self) -> None:
        self.law.prepare()
