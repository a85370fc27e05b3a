"""A follower's control law: the one the scenario names (``controller.law``).

``make_controller`` builds it for a follower's role (agents.follower_role),
or for the one-process loop (formation_swarm.studies.sim), from a
ControllerSetup; it is the one place a law's name becomes a class of
agents.controller's API: a built-in one (``BUILT_IN``), else one that
agents.laws finds (``module:Class`` or an entry point). Every class is
built as ``Class(setup)``.

FollowerParams (agents.params) and both built-in controllers are
importable from here too: one import for a follower's law.
"""

from __future__ import annotations

from dataclasses import replace

from formation_swarm.agents.controller import ControllerSetup, FollowerController
from formation_swarm.agents.fuzzy_controller import FuzzyController, change_over
from formation_swarm.agents.laws import declared_params, find_class
from formation_swarm.agents.lpsi_controller import LpsiController
from formation_swarm.agents.params import LAWS, FollowerParams
from formation_swarm.agents.tracking import TrackingController

__all__ = [
    "BUILT_IN",
    "LAWS",
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
    cls = law_class(setup.params.law)
    # Its declared defaults, the scenario's values over them, the setup's over both.
    params = {**declared_params(cls), **dict(setup.params.law_params), **setup.law_params}
    controller: FollowerController = cls(replace(setup, law_params=params))
    return controller
