"""Every key a scenario file may hold: its type, unit, default, range and
meaning. The loader (``formation_swarm.spec.scenario``) checks files against these
tables, and ``docs/scenario.md`` is generated from them by ``keys_doc``
(``python -m formation_swarm.spec.keys_doc > docs/scenario.md``; a test fails
when the file is stale), so the document and the checks cannot disagree.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from formation_swarm.agents.ekf import EkfParams
from formation_swarm.agents.follower import FollowerParams
from formation_swarm.agents.fuzzy import FuzzyParams
from formation_swarm.common.checks import SEED_MAX

# The world's ground truth lists every robot in one message, and the leader's
# observation every obstacle in range: both must fit protocol.codec.MAX_PAYLOAD_BYTES
# (tests/unit/protocol/test_messages.py encodes the largest ones).
MAX_ROBOTS = 500
MAX_OBSTACLES = 500
# Tables and arrays inside each other, the file itself the first: a scenario
# needs 6 (formations.NAME.slots.ID.offset); TOML's reader recurses per level.
MAX_DEPTH = 32


class ScenarioError(ValueError):
    """A scenario that cannot run; the message names the key. ``key`` (dotted,
    as the file writes it) and ``value``: the key at fault and its value, where
    the check that refused it gives them (None where it does not)."""

    def __init__(self, message: str, key: str | None = None, value: Any = None) -> None:
        super().__init__(message)
        self.key = key
        self.value = value


class ScenarioWarning(UserWarning):
    """A scenario that runs, but not as its author likely expects (the loader
    warns with it through ``warnings.warn``)."""


REQUIRED = object()  # the default of a key that must be given
NUM = (int, float)


@dataclass(frozen=True)
class Key:
    """One scenario key. ``low``/``high`` bound a number (``open_low``: strictly above ``low``)."""

    types: type | tuple[type, ...]
    default: Any
    doc: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    open_low: bool = False

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def range_text(self) -> str:
        def num(v: float) -> str:
            return "2**63 - 1" if v == SEED_MAX else str(v) if isinstance(v, int) else f"{v:g}"

        if self.low is None and self.high is None:
            return ""
        if self.high is None:
            return f"{'>' if self.open_low else '>='} {num(self.low)}"
        return f"{'(' if self.open_low else '['}{num(self.low)}, {num(self.high)}]"

    def check_range(self, where: str, value: Any) -> str | None:
        """Why ``value`` is out of range, or None."""
        if isinstance(value, bool) or not isinstance(value, NUM):
            return None
        too_low = self.low is not None and (value <= self.low if self.open_low else value < self.low)
        too_high = self.high is not None and value > self.high
        if too_low or too_high:
            bound = self.range_text() if self.high is None else "in " + self.range_text()
            return f"{where} must be {bound}, got {value!r}"
        return None


def positive(doc: str, default: Any = REQUIRED, unit: str = "") -> Key:
    return Key(NUM, default, doc, unit, low=0.0, open_low=True)


def non_negative(doc: str, default: Any = REQUIRED, unit: str = "") -> Key:
    return Key(NUM, default, doc, unit, low=0.0)


RUN_KEYS = {
    "name": Key(str, "scenario", "the run's name: the start of its run id and folder"),
    "seed": Key(
        int, 0, "seed of every random draw (camera noise, link drops and faults, wheel noise)", low=0, high=SEED_MAX
    ),
    "robots": Key(int, REQUIRED, "how many robots; ids run from leader.id upward", low=2, high=MAX_ROBOTS),
    "dt_s": positive("the tick: the world's integration step and the agents' control period", 0.05, "s"),
    "duration_s": positive("the run's length in sim time", unit="s"),
    "lockstep_deadline_s": positive(
        "lockstep: how long the world waits for an agent's answer before counting a miss and stopping it; a miss "
        "no scheduled fault explains makes the run not reproducible (it fails)",
        2.0,
        "s",
    ),
    "stale_after_s": positive("a robot whose latest command is older than this is stopped", 0.5, "s"),
    "agents_per_process": Key(int, 1, "swarm run: robots per agent process, a session each", low=1, high=MAX_ROBOTS),
    "record_every": Key(
        int,
        1,
        "the logger records every N-th tick's truth and telemetry alone (the recording's size over N; the "
        "summary's target errors from those ticks)",
        low=1,
        high=1000,
    ),
}
ROBOT_KEYS = {
    "width_m": positive("wheel base: the distance between the two wheels (eq. 7-10)", 0.5, "m"),
    "marker_offset_m": non_negative("how far behind the robot's centre its marker sits", 0.1, "m"),
    "diameter_m": positive("body diameter: two robots closer than this collide", 0.4, "m"),
    "max_wheel_mps": positive(
        "the fastest a wheel turns, either way: the world refuses a command beyond it (and clamps what it"
        " executes), and every controller of the scenario must stay within it",
        3.0,
        "m/s",
    ),
    "wheel_noise_mps": non_negative(
        "standard deviation of the Gaussian noise on each wheel's speed, per tick: the paper's process noise on"
        " the robots' motion, on every robot for the whole run (a robot at rest does not jitter; the"
        " wheel_noise fault adds noise to some robots for a while)",
        0.0,
        "m/s",
    ),
}
CAMERA_KEYS = {
    "fov_deg": Key(NUM, 360.0, "field of view, centred on the heading", "deg", low=0.0, high=360.0, open_low=True),
    "range_m": positive("farthest marker the camera sees", 10.0, "m"),
    "sigma_rho_m": non_negative("standard deviation of the measured marker distance", 0.05, "m"),
    "sigma_phi_deg": non_negative("standard deviation of the measured leader orientation", 3.0, "deg"),
    "sigma_beta_deg": non_negative("standard deviation of the measured bearing", 1.5, "deg"),
}
LEADER_KEYS = {
    "id": Key(int, 1, "the leader's robot id; followers take the next ids", low=1),
    "speed_mps": positive("cruise speed along the path", 1.5, "m/s"),
    "turn_rate_rps": positive("the pilot's largest turn rate", 0.25, "rad/s"),
    "lookahead_m": positive("pure pursuit: the pilot steers toward the point this far ahead on the path", 1.0, "m"),
    "corners": Key(
        str,
        "pursuit",
        "'pursuit': pure pursuit of the waypoints' polyline, turning at the look-ahead and overshooting a corner"
        " by about speed_mps / turn_rate_rps (the shipped scenarios); 'arcs': each corner flown on a circle of"
        " that radius, started before the corner",
    ),
    "waypoints": Key(list, REQUIRED, "the path, at least two points [x_m, y_m]; the run starts at the first", "m"),
    "sensing_range_m": positive("the leader switches to avoid_formation when an obstacle is this close", 6.0, "m"),
    "formation": Key(str, REQUIRED, "the formation flown at the start and when the way is clear (a [formations] name)"),
    "avoid_formation": Key(str, "", "the formation flown near obstacles (a [formations] name); empty: never switch"),
    "clear_after_s": positive("back to the normal formation after no obstacle has been in range this long", 2.0, "s"),
    "code_burst_s": non_negative(
        "after a formation change the leader sends its code every tick for this long", 1.0, "s"
    ),
    "code_period_s": positive("otherwise it repeats its current code this often", 0.5, "s"),
    "policy": Key(
        str,
        "path",
        "what flies the leader: 'path' (the paper's: the waypoints, the formation switch near obstacles and the"
        " code repeats above), or a policy of your own: 'package.module:Class' or the name of an entry point of the"
        " group formation_swarm.leader_policies (docs/controllers.md). Any policy starts at the first waypoint,"
        " heading to the second, and the world takes its 'done' only at the last waypoint",
    ),
    "params": Key(
        dict,
        {},
        "the policy's own parameters, a table of name = value: those its class declares in PARAMS"
        " (docs/controllers.md); 'path' takes none",
    ),
}
SHAPES = ("wedge", "line", "abreast", "grid", "custom")
FORMATION_KEYS = {
    "shape": Key(
        str,
        REQUIRED,
        "'wedge' (a V behind the leader; tree depth n // 2, 2 for 3 robots), 'line' (single file; depth n - 1,"
        " or that of the wedge with follow = 'pairs'), 'abreast' (level with the leader, which flies in the middle;"
        " depth n // 2), 'grid' (rows behind the leader; depth at most rows - 1 + (columns + 1) // 2) or 'custom'. The"
        " depth is the longest chain of references from a follower to the leader, n the number of robots."
        " Every follower's reference must be within the camera's range less the controller's dmax_m, and within"
        " its field of view less gamma_deg, seen from the follower's slot, and so must a new reference at a"
        " switch between leader.formation and leader.avoid_formation, seen from the old slot: the loader"
        " rejects a formation that is not",
    ),
    "lateral_m": positive(
        "wedge: followers fly in ranks r = 1, 2, ... (two per rank, the 1st, 3rd, ... on the left), each rank"
        " r * lateral_m to the side of the leader's track; grid: the distance between columns",
        1.5,
        "m",
    ),
    "back_m": positive(
        "wedge: and r * back_m behind the leader; the ranks of each wing each follow the rank before them on"
        " their side (rank 1: the leader; with 3 robots the right one follows the left one, as in the paper's"
        " triangle); grid: the distance between rows",
        1.5,
        "m",
    ),
    "spacing_m": positive(
        "line: distance between consecutive robots; abreast: distance between neighbours, each following its"
        " neighbour toward the leader",
        1.5,
        "m",
    ),
    "follow": Key(
        str,
        "ahead",
        "line: 'ahead' (each robot follows the one ahead) or 'pairs' (robot 2 the leader, then each the one"
        " two places ahead, robot 3 the leader; with 3 robots the one ahead: the references of a wedge, so that"
        " a switch between a wedge and a line changes offsets only; with the default spacings, needed to switch"
        " with more than 6 robots)",
    ),
    "columns": Key(
        int,
        3,
        "grid: robots per row, filled from the centre out; each follows the robot ahead in its column, the"
        " first row the leader (centre columns) or its neighbour toward the centre",
        low=1,
    ),
    "slots": Key(dict, {}, "custom: per follower id, { reference = ID, offset = [x_m, y_m] } in the reference's frame"),
}
SLOT_KEYS = {
    "reference": Key(int, REQUIRED, "the robot this follower follows"),
    "offset": Key(list, REQUIRED, "[x_m, y_m] of the virtual target in the reference's frame (x right, y ahead)", "m"),
}

_EKF_DOCS = {
    "sigma_rho_m": ("measurement noise of rho assumed by the filter", "m"),
    "sigma_phi_rad": ("measurement noise of phi assumed by the filter", "rad"),
    "sigma_beta_rad": ("measurement noise of beta assumed by the filter", "rad"),
    "q_pos_m": ("process noise density of the target's position", "m/sqrt(s)"),
    "q_phi_rad": ("process noise density of the reference's orientation", "rad/sqrt(s)"),
    "q_speed_mps": ("process noise density of the reference's speed", "m/s/sqrt(s)"),
    "q_turn_rps": ("process noise density of the reference's turn rate", "rad/s/sqrt(s)"),
    "initial_speed_sigma_mps": ("initial standard deviation of the reference's speed", "m/s"),
    "initial_turn_sigma_rps": ("initial standard deviation of the reference's turn rate", "rad/s"),
}
_EKF_DEFAULTS = EkfParams()


def _ekf_key(name: str) -> Key:
    doc, unit = _EKF_DOCS[name]  # a new EkfParams field needs its line above
    make = non_negative if name.startswith("q_") else positive
    return make(doc, getattr(_EKF_DEFAULTS, name), unit)


EKF_KEYS = {f.name: _ekf_key(f.name) for f in fields(EkfParams)}
_FZ = FuzzyParams()
_FOLLOWER = FollowerParams()
CONTROLLER_KEYS = {
    "vn": Key(
        (str, int, float), "dynamic", "V_N, the nominal wheel speed: 'dynamic' (FIS-2 picks it) or a number", "m/s"
    ),
    "use_ekf": Key(bool, True, "steer on the EKF's estimate of the target (false: on the raw camera reading)"),
    "clearance_m": positive("partition-zone collision avoidance (eq. 13): the clearance kept while changing", 1.0, "m"),
    "lost_after_s": positive("with no reading for this long the follower stops and waits", 1.0, "s"),
    "hold_speed_mps": non_negative(
        "the hold at a standing reference (not the paper's; docs/paper.md): the reference stands still once the"
        " mean of the EKF's estimate of its speed over hold_after_s is below this, and the follower then stops at"
        " its target; 0: never hold (nor without the EKF)",
        _FOLLOWER.hold_speed_mps,
        "m/s",
    ),
    "resume_speed_mps": non_negative(
        "the hold ends once that mean is above this (>= hold_speed_mps): the reference moves again",
        _FOLLOWER.resume_speed_mps,
        "m/s",
    ),
    "hold_after_s": positive(
        "the window of that mean: how long the reference must stand still", _FOLLOWER.hold_after_s, "s"
    ),
    "wait_ahead": Key(
        bool,
        _FOLLOWER.wait_ahead,
        "the wait ahead of the target (not the paper's; docs/paper.md, formations of many robots): a fuzzy"
        " follower more than dn_m ahead of its target stops until the target is within d0_m (false: it drives on"
        " at V_N - a, as the paper's does)",
    ),
    "lookahead_m": non_negative(
        'the steering look-ahead (not the paper\'s; docs/paper.md, "The steering look-ahead"): a fuzzy follower'
        " steers at the point this far ahead of its target along its reference's heading, which keeps heading"
        " swings from growing down chains of references (0: at the target, as the paper's)",
        _FOLLOWER.lookahead_m,
        "m",
    ),
    "gamma_deg": Key(
        NUM, math.degrees(_FZ.gamma_rad), "FIS-1 heading tolerance", "deg", low=0.0, high=180.0, open_low=True
    ),
    "d0_m": non_negative(
        "FIS-1 distance-error breakpoint d0 (sec. 4.1): below it the target is reached", _FZ.d0_m, "m"
    ),
    "dn_m": positive("FIS-1 breakpoint dn, > d0_m", _FZ.dn_m, "m"),
    "d1_m": positive("FIS-1 breakpoint d1, >= dn_m", _FZ.d1_m, "m"),
    "dmax_m": positive("FIS-1 breakpoint dmax, > d1_m: beyond it the error is Far", _FZ.dmax_m, "m"),
    "a_mps": positive("FIS-1: width of the Medium wheel-speed set", _FZ.a_mps, "m/s"),
    "vn_min": positive("FIS-2: the Low V_N", _FZ.vn_min, "m/s"),
    "vm": positive("FIS-2: the Middle V_N", _FZ.vm, "m/s"),
    "vn_max": positive("FIS-2: the High V_N", _FZ.vn_max, "m/s"),
    "drho_rate_tol_mps": positive(
        "FIS-2: |drho|/dt at which Positive and Negative saturate", _FZ.drho_rate_tol_mps, "m/s"
    ),
    "ekf": Key(dict, {}, "the EKF's noise model: a table of the [controller.ekf] keys below"),
    "law": Key(
        str,
        "fuzzy",
        "'fuzzy' (the paper's controller), 'lpsi' (the l-psi baseline of Desai et al.), or a controller of your"
        " own: 'package.module:Class' or the name of an entry point of the group formation_swarm.controllers"
        " (docs/controllers.md)",
    ),
    "drho_at_sign_change": Key(
        str,
        "signed",
        "eq. 6 where the signed rho changes sign (a follower level with its target, to its side): 'signed' takes"
        " the jump of 2 |rho| (FIS-2 sees it as a fast approach), 'distance' the change of |rho|",
    ),
    "lpsi_l_gain": positive("l-psi: distance gain a1", 1.0, "1/s"),
    "lpsi_psi_gain": positive("l-psi: bearing gain a2", 1.0, "1/s"),
    "lpsi_d_m": positive("l-psi: the controlled point, ahead of the axle", 0.25, "m"),
}
# A law's own parameters: checked against what its class declares (spec.controllers), not here.
CONTROLLER_KEYS["params"] = Key(
    dict,
    {},
    "the law's own parameters, a table of name = value: those its class declares in PARAMS"
    " (docs/controllers.md); the built-in laws take none. A [followers.ID] table's params go over these"
    " name by name, unless it names another law",
)
# The partition-zone avoidance's switch, a block of its own: the law's keys are above.
CONTROLLER_KEYS["avoidance"] = Key(
    bool,
    _FOLLOWER.avoidance,
    "the partition-zone collision avoidance during a formation change (eq. 11-13, the paper's): false, a"
    " fuzzy follower goes straight to its new slot (eq. 13 skipped; the ablation of docs/results.md, claim d)",
)
OBSTACLE_KEYS = {
    "x_m": Key(NUM, REQUIRED, "centre x", "m"),
    "y_m": Key(NUM, REQUIRED, "centre y", "m"),
    "radius_m": positive("radius", unit="m"),
}
LINK_KEYS = {
    "obs_drop": Key(NUM, 0.0, "probability that a world -> agent observation is lost", low=0.0, high=1.0),
    "cmd_drop": Key(NUM, 0.0, "probability that an agent -> world command is lost", low=0.0, high=1.0),
    "formation_drop": Key(NUM, 0.0, "probability that a leader -> follower formation code is lost", low=0.0, high=1.0),
}
ROS2_DISTROS = ("jazzy",)  # whose rmw_zenoh wire format swarm run --ros2 speaks
ROS2_KEYS = {
    "bridge": Key(bool, False, "swarm run starts the ROS 2 bridge (swarm run --ros2 sets it)"),
    "domain_id": Key(int, 0, "the ROS 2 domain the bridge's topics are in (ROS_DOMAIN_ID)", low=0, high=232),
    "namespace": Key(str, "", "put every topic under this namespace, e.g. fleet (frames keep their names)"),
    "distro": Key(str, "jazzy", f"the ROS 2 distro whose wire format to speak: {', '.join(ROS2_DISTROS)}"),
}

# The file's sections: name -> (keys, what the section is, how it appears in TOML).
SECTIONS: dict[str, tuple[Mapping[str, Key], str, str]] = {
    "run": (RUN_KEYS, "the run as a whole", "[run]"),
    "robot": (ROBOT_KEYS, "every robot's body", "[robot]"),
    "camera": (CAMERA_KEYS, "every robot's camera: what it measures of the marker ahead", "[camera]"),
    "leader": (LEADER_KEYS, "the leader: its path, its obstacle sensing, its formation codes", "[leader]"),
    "formations": (
        FORMATION_KEYS,
        "named formations; codes are their indices in file order (at most 256)",
        "[formations.NAME]",
    ),
    "formations.NAME.slots": (SLOT_KEYS, "one follower's place in a custom formation", "[formations.NAME.slots.ID]"),
    "controller": (CONTROLLER_KEYS, "every follower's controller", "[controller]"),
    "controller.ekf": (EKF_KEYS, "the EKF's noise model (sec. 3)", "[controller.ekf]"),
    "followers": (
        CONTROLLER_KEYS,
        "per-follower overrides of [controller], any of its keys",
        "[followers.ID]",
    ),
    "obstacles": (OBSTACLE_KEYS, f"round obstacles (at most {MAX_OBSTACLES})", "[[obstacles]]"),
    "links": (LINK_KEYS, "faults of the one-way links: each message is dropped with this probability", "[links]"),
    "ros2": (ROS2_KEYS, "the ROS 2 bridge of swarm run --ros2 (docs/ros2.md)", "[ros2]"),
}
TOP_KEYS = ("run", "robot", "camera", "leader", "formations", "controller", "followers", "obstacles", "links")
TOP_KEYS += ("faults", "placement", "ros2")


def type_name(types: type | tuple[type, ...]) -> str:
    if isinstance(types, tuple):
        names = {t.__name__ for t in types}
        if names >= {"int", "float"}:
            names = (names - {"int", "float"}) | {"a number"}
        return " or ".join({"str": "a string", "bool": "true or false"}.get(n, n) for n in sorted(names))
    return {"list": "an array", "dict": "a table", "str": "a string", "bool": "true or false", "int": "an integer"}.get(
        types.__name__, types.__name__
    )
