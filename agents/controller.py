"""The follower controller API: what a follower's control law gets and gives.

A controller is a class built from one :class:`ControllerSetup`: its robot
id, the run's follower parameters, its own parameters (``law_params``), the
slot it starts in and the wheels' limit. The role calls its ``step`` once
for every tick it answers, with what the robot itself has
(:class:`FollowerInput`):

- ``reading``: its camera's reading of its reference's marker
  (:class:`MarkerReading`: rho_m, phi_rad, beta_rad, paper eq. 1), or None
  when the marker is not seen this tick;
- ``slot``: where it must be in the current formation
  (agents.formation.Slot: the reference's robot id, the offset in the
  reference's frame, x right and y ahead, m);
- ``slot_moved``: a new formation moved the slot since the last step, so a
  formation change starts; ``new_reference``: it named another reference,
  whose readings start afresh;
- ``ticks``, ``dt_s``: the ticks and seconds since the last step (more
  than one tick where the agent skipped observations or was frozen).

``step`` returns a :class:`FollowerOutput`: the wheel speeds and named
telemetry values (name -> float). A controller may keep state between
steps; it does no I/O. Everything else is the role's
(agents.follower_role): links, inbox checks, formation codes, messages.

The role sends the names of ``WIRE_TELEMETRY`` to the logger in the
Telemetry message's fields (protocol.messages.Telemetry); NaN or absent
means "none this tick". It counts the ticks with ``holding`` or
``waiting`` above 0 and reports ``ekf_resets`` in its stats
(``ROLE_COUNTED``). Any other name is the controller's own: it travels in
the message's ``extras`` (at most protocol.messages.MAX_EXTRAS names, each
a protocol.messages.EXTRA_NAME) and the logger records it under the robot.

A controller that raises, or returns a speed that is not a finite number,
has failed: the role stops its robot for the rest of the run and never
calls it again (docs/controllers.md).

A controller may also define ``prepare()``: the role calls it once the
tick's command is sent, while the robot waits for its next observation, so
that work such as the EKF's prediction leaves the tick's critical path.

The implementations: agents.fuzzy_controller.FuzzyController (the paper's
EKF, FIS-2, FIS-1 and eq. 11-13) and agents.lpsi_controller.LpsiController
(the l-psi baseline). agents.follower.make_controller picks one by the
scenario's ``controller.law``, or a user's class (agents.laws).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from formation_swarm.agents.formation import Slot
from formation_swarm.agents.params import FollowerParams

__all__ = [
    "ROLE_COUNTED",
    "WIRE_TELEMETRY",
    "ControllerFactory",
    "ControllerSetup",
    "FollowerController",
    "FollowerInput",
    "FollowerOutput",
    "MarkerReading",
    "Slot",
]

WIRE_TELEMETRY = (
    "measured_x_m",  # the target from this tick's reading (eq. 1-2), follower frame
    "measured_y_m",
    "estimate_x_m",  # the target from the EKF's estimate
    "estimate_y_m",
    "estimate_cov_xx_m2",  # the covariance of that estimate
    "estimate_cov_xy_m2",
    "estimate_cov_yy_m2",
    "rho_m",  # the distance error (eq. 5)
    "alpha_rad",  # the heading error (eq. 4)
    "vn_mps",  # FIS-2's speed V_N
    "steering_to",  # eq. 13's target: 0 (T0) to 3 (T3)
    "changing",  # 1 while a formation change is under way
)
ROLE_COUNTED = ("holding", "waiting", "ekf_resets")


@dataclass(frozen=True, kw_only=True, slots=True)
class MarkerReading:
    """The camera's reading of the reference's marker (paper eq. 1)."""

    rho_m: float  # distance to the marker
    phi_rad: float  # the reference's heading relative to ours
    beta_rad: float  # bearing of the marker, positive to the right


@dataclass(frozen=True, kw_only=True, slots=True)
class ControllerSetup:
    """What a controller is built from."""

    robot_id: int
    params: FollowerParams  # the run's: dt_s, width_m, marker_offset_m, lost_after_s; the built-in laws' own
    slot: Slot  # the slot of the formation the run starts in
    # The law's own parameters: its class's PARAMS with the scenario's [controller.params] over them.
    law_params: Mapping[str, Any] = field(default_factory=dict)
    max_wheel_mps: float = math.inf  # robot.max_wheel_mps: the world refuses a faster wheel command


@dataclass(frozen=True, kw_only=True, slots=True)
class FollowerInput:
    """What the robot has at one tick it answers."""

    reading: MarkerReading | None
    slot: Slot
    slot_moved: bool = False
    new_reference: bool = False
    ticks: int = 1
    dt_s: float


@dataclass(frozen=True, kw_only=True, slots=True)
class FollowerOutput:
    """The wheel speeds to command, and named telemetry values."""

    left_mps: float
    right_mps: float
    telemetry: Mapping[str, float] = field(default_factory=dict)


class FollowerController(Protocol):
    """A follower's control law; see the module's docstring."""

    def step(self, inp: FollowerInput) -> FollowerOutput: ...


ControllerFactory = Callable[[ControllerSetup], FollowerController]
