"""A follower's control law: the one the scenario names (``controller.law``).

``make_controller`` builds it for a follower's role (agents.follower_role)
from a ControllerSetup; it is the one place a law's name becomes a class
of agents.controller's API: a built-in one (``BUILT_IN``), else one that
agents.laws finds (``module:Class`` or an entry point), built as
``Class(setup)``. ``Follower`` is the same controller driven by
hand, with raw readings and formation slots, without a role: the
one-process replays (tests.helpers.replica, formation_swarm.studies.sim)
and the benchmarks use it.

FollowerParams (agents.params), Decision (agents.tracking) and both
controllers are importable from here too: one import for a follower's law.
"""

from __future__ import annotations

from dataclasses import replace

from formation_swarm.agents.controller import ControllerSetup, FollowerController
from formation_swarm.agents.fuzzy_controller import FuzzyController, change_over
from formation_swarm.agents.geometry import Point
from formation_swarm.agents.laws import declared_params, find_class
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
    "law_class",
    "make_controller",
]

# One class per name of agents.params.LAWS.
BUILT_IN: dict[str, type[TrackingController]] = {"fuzzy": FuzzyController, "lpsi": LpsiController}


def law_class(law: str) -> type:
    """The class of the law ``law`` names (agents.laws.LawError if none)."""
    built_in = BUILT_IN.get(law)
    return built_in if built_in is not None else find_class(law)


def make_controller(setup: ControllerSetup) -> FollowerController:
    """The controller of the law ``setup.params.law`` names."""
    built_in = BUILT_IN.get(setup.params.law)
    if built_in is not None:
        return built_in.from_setup(setup)
    cls = find_class(setup.params.law)
    # Its declared defaults, the scenario's values over them, the setup's over both.
    params = {**declared_params(cls), **dict(setup.params.law_params), **setup.law_params}
    controller: FollowerController = cls(replace(setup, law_params=params))
    return controller


class Follower:
    """One follower's controller (``params.law``) driven by hand: a reading
    (rho_r, phi, beta) or None in, a Decision out; the slot set by calls."""

    def __init__(self, params: FollowerParams, offset: Point) -> None:
        if params.law not in BUILT_IN:
            raise ValueError(f"Follower drives the built-in laws only ({', '.join(BUILT_IN)}), got {params.law!r}")
        self.law = BUILT_IN[params.law](params, offset)

    def step(self, reading: Reading | None, ticks: int = 1) -> Decision:
        return self.law.decide(reading, ticks)

    def set_offset(self, offset: Point) -> None:
        self.law.set_offset(offset)

    def new_reference(self) -> None:
        self.law.new_reference()

    def prepare(self) -> None:
        self.law.prepare()
