"""The follower controller API: what a follower's control law gets and gives.

A controller is a class built from one :class:`ControllerSetup`: its robot
id, the run's follower parameters, its own parameters (``law_params``), the
slot it starts in and the wheels' limit. The role calls its ``step`` once
for every tick it answers, with what the robot itself has
(:class:`FollowerInput`):

- ``reading``: its camera's reading of its reference's marker
  (:class:`MarkerReading`: rho_m, phi_rad, beta_rad, paper eq. 1), or None
  when the marker is not seen this tick;
- ``slot``: where it must be in the current formation (:class:`Slot`: the
  reference's robot id, the offset in the reference's frame, x right and
  y ahead, m);
- ``slot_moved``: a new formation moved the slot since the last step, so a
  formation change starts; ``new_reference``: it named another reference,
  whose readings start afresh;
- ``ticks``, ``dt_s``: the ticks and seconds since the last step (more
  than one tick where the agent skipped observations or was frozen).

``step`` returns a :class:`FollowerOutput`: the wheel speeds, where it
estimates its target is (:class:`TargetEstimate`, or None), why it stands
still (``stop``, or None while it drives) and named values (name -> float).
A controller may keep state between steps; it does no I/O. Everything else
is the role's (agents.follower_role): links, inbox checks, formation codes,
messages.

The role fills the Telemetry message (protocol.messages.Telemetry) from
the output: the estimate and its covariance from ``target``, and the
fields named in ``WIRE_VALUES`` from the values of those names (NaN or
absent: "none this tick"). It counts the ticks stopped for the reasons of
``COUNTED_STOPS`` and reports the running count ``ekf_resets``
(``STATS_VALUES``) in its stats. Any other name is the controller's own: it
travels in the message's ``extras`` (at most protocol.messages.MAX_EXTRAS
names, each a protocol.messages.EXTRA_NAME) and the logger records it
under the robot.

A controller that raises, or returns a speed that is not a finite number,
has failed: the role stops its robot for the rest of the run and never
calls it again (docs/controllers.md).

A controller may also define ``prepare()``: the role calls it once the
tick's command is sent, while the robot waits for its next observation, so
that work such as the EKF's prediction leaves the tick's critical path.
And ``reset()``, called once before its first step, and ``close()``, called
once when its agent stops (agents.hooks).

The implementations: agents.fuzzy_controller.FuzzyController (the paper's
EKF, FIS-2, FIS-1 and eq. 11-13) and agents.lpsi_controller.LpsiController
(the l-psi baseline). agents.follower.make_controller picks one by the
scenario's ``controller.law``, or a user's class (agents.laws).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from formation_swarm.agents.formation import Slot
from formation_swarm.agents.geometry import MarkerReading, Point
from formation_swarm.agents.params import FollowerParams
from formation_swarm.common.checks import positive

__all__ = [
    "COUNTED_STOPS",
    "HOLDING",
    "LOST",
    "STATS_VALUES",
    "WAITING",
    "WIRE_VALUES",
    "ControllerSetup",
    "FollowerController",
    "FollowerInput",
    "FollowerOutput",
    "FollowerParams",
    "MarkerReading",
    "Point",
    "Slot",
    "TargetEstimate",
]

# The named values the role sends in the Telemetry message's own fields.
WIRE_VALUES = (
    "measured_x_m",  # the target from this tick's reading (eq. 1-2), follower frame -> measured
    "measured_y_m",
    "rho_m",  # the distance error (eq. 5) -> rho_m
    "alpha_rad",  # the heading error (eq. 4) -> alpha_rad
    "vn_mps",  # FIS-2's speed V_N -> vn
    "steering_to",  # eq. 13's target: 0 (T0, the slot's) to 3 (T3) -> steering_to, an integer
    "changing",  # > 0 while a formation change is under way -> changing
)
STATS_VALUES = ("ekf_resets",)  # a running count, in the agent's stats; not sent

# Why a robot stands still (FollowerOutput.stop): the built-in laws' reasons.
HOLDING = "holding"  # at its target, its reference standing still
WAITING = "waiting"  # ahead of its target, for the target to come
LOST = "lost"  # no sight of its reference: not seen for lost_after_s, never seen, or its estimate restarting
COUNTED_STOPS = (HOLDING, WAITING)  # the agent's stats count these (held_ticks and holds, waited_ticks)


@dataclass(frozen=True, kw_only=True, slots=True)
class ControllerSetup:
    """What a controller is built from."""

    robot_id: int
    params: FollowerParams  # the run's: dt_s, width_m, marker_offset_m, lost_after_s; the built-in laws' own
    slot: Slot  # the slot of the formation the run starts in
    max_wheel_mps: float  # robot.max_wheel_mps: the world refuses a faster wheel command
    # The law's own parameters: its class's PARAMS with the scenario's [controller.params] over them.
    law_params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        positive("max_wheel_mps", self.max_wheel_mps)


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
class TargetEstimate:
    """Where the controller estimates its target (its slot's point) is, in
    the follower's frame (x right, y ahead)."""

    x_m: float
    y_m: float
    cov_m2: tuple[float, float, float] | None = None  # (xx, xy, yy) of (x_m, y_m); None: none known


@dataclass(frozen=True, kw_only=True, slots=True)
class FollowerOutput:
    """What a controller answers a tick with."""

    left_mps: float  # the wheel speeds to command
    right_mps: float
    target: TargetEstimate | None = None
    # Why the robot stands still this tick (HOLDING, WAITING, LOST or a word of the controller's own); None: it drives.
    stop: str | None = None
    values: Mapping[str, float] = field(default_factory=dict)  # named values: WIRE_VALUES, STATS_VALUES, its own


class FollowerController(Protocol):
    """A follower's control law; see the module's docstring."""

    def step(self, inp: FollowerInput) -> FollowerOutput: ...
