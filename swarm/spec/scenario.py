"""Scenario files (TOML): robots, formations, the leader's path, obstacles,
noise, controller parameters, link faults, seed, dt and duration.

A scenario is named by a path to its file or by the name of a shipped one
(``fig11_obstacles``: ``scenarios/*.toml``, installed with the package).
Unknown keys are errors that name the key and suggest the closest valid one;
invalid values are errors that name the key and the value.
"""

from __future__ import annotations

import difflib
import itertools
import json
import math
import tomllib
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from formation_swarm.agents.ekf import EkfParams
from formation_swarm.agents.follower import FollowerParams
from formation_swarm.agents.formation import (
    Camera,
    Formation,
    Slot,
    abreast,
    check_sight,
    check_switch,
    grid,
    line,
    wedge,
)
from formation_swarm.agents.fuzzy import FuzzyParams, SpeedMode, speed_range
from formation_swarm.agents.geometry import Point
from formation_swarm.agents.lpsi import LpsiParams
from formation_swarm.agents.pilot import CORNERS, turn_room
from formation_swarm.common.fault_schedule import check_against, past_the_end
from formation_swarm.common.faults import Fault, parse_all
from formation_swarm.protocol.keys import MAX_ROBOT_ID, check_host_name
from formation_swarm.spec.files import deep_set, resolve
from formation_swarm.spec.keys import (
    CAMERA_KEYS,
    CONTROLLER_KEYS,
    EKF_KEYS,
    FORMATION_KEYS,
    LEADER_KEYS,
    LINK_KEYS,
    MAX_OBSTACLES,
    NUM,
    OBSTACLE_KEYS,
    ROBOT_KEYS,
    RUN_KEYS,
    SECTIONS,
    SHAPES,
    SLOT_KEYS,
    TOP_KEYS,
    Key,
    ScenarioError,
    ScenarioWarning,
    type_name,
)
from formation_swarm.world.camera import CameraParams


@dataclass(frozen=True)
class Obstacle:
    x_m: float
    y_m: float
    radius_m: float


@dataclass(frozen=True)
class LeaderSpec:
    robot_id: int
    speed_mps: float
    turn_rate_rps: float
    lookahead_m: float
    corners: str
    waypoints: tuple[tuple[float, float], ...]
    sensing_range_m: float
    formation: str
    avoid_formation: str | None
    clear_after_s: float
    code_burst_s: float
    code_period_s: float


@dataclass(frozen=True)
class LinkFaults:
    obs_drop: float = 0.0
    cmd_drop: float = 0.0
    formation_drop: float = 0.0


@dataclass(frozen=True)
class Scenario:
    name: str
    seed: int
    dt_s: float
    duration_s: float
    lockstep_deadline_s: float
    stale_after_s: float
    robots: tuple[int, ...]
    width_m: float
    diameter_m: float
    max_wheel_mps: float
    camera: CameraParams
    leader: LeaderSpec
    formations: Mapping[str, Formation]
    followers: Mapping[int, FollowerParams]
    obstacles: tuple[Obstacle, ...]
    links: LinkFaults
    raw: Mapping[str, Any] = field(repr=False, compare=False)
    faults: tuple[Fault, ...] = ()  # the fault schedule, by start time (formation_swarm.common.faults)
    wheel_noise_mps: float = 0.0  # robot.wheel_noise_mps: every wheel, every tick
    # What may make the run say little, found at load (speed_warnings); not errors.
    warnings: tuple[str, ...] = field(default=(), compare=False)
    placement: tuple[tuple[int, str], ...] = ()  # [placement]: (robot, host) for runs on hosts

    @property
    def formation_names(self) -> tuple[str, ...]:
        """Formation codes are indices into this tuple."""
        return tuple(self.formations)

    def code_of(self, name: str) -> int:
        return self.formation_names.index(name)

    def formation_by_code(self, code: int) -> Formation:
        return self.formations[self.formation_names[code]]

    @property
    def follower_ids(self) -> tuple[int, ...]:
        return tuple(r for r in self.robots if r != self.leader.robot_id)

    @property
    def ticks(self) -> int:
        return int(round(self.duration_s / self.dt_s))

    def with_seed(self, seed: int) -> Scenario:
        raw = deep_set(self.raw, ("run", "seed"), seed)
        return replace(self, seed=seed, raw=raw)


def _suggest(key: str, valid: list[str] | tuple[str, ...]) -> str:
    close = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else f"; valid keys: {', '.join(valid)}"


def _table(raw: Any, where: str, schema: Mapping[str, Key]) -> dict[str, Any]:
    """Check one table against its schema (types and ranges); fill defaults; reject unknown keys."""
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise ScenarioError(f"{where} must be a table, got {type(raw).__name__}")
    out: dict[str, Any] = {}
    for key, value in raw.items():
        if key not in schema:
            raise ScenarioError(f"unknown key {where}.{key}" + _suggest(key, tuple(schema)))
        spec = schema[key]
        types = spec.types if isinstance(spec.types, tuple) else (spec.types,)
        if (isinstance(value, bool) and bool not in types) or not isinstance(value, types):
            got = str(value).lower() if isinstance(value, bool) else repr(value)  # as TOML writes it
            raise ScenarioError(f"{where}.{key} must be {type_name(spec.types)}, got {got}")
        if isinstance(value, float) and not math.isfinite(value):
            raise ScenarioError(f"{where}.{key} must be finite, got {value!r}")
        if (why := spec.check_range(f"{where}.{key}", value)) is not None:
            raise ScenarioError(why)
        out[key] = value
    for key, spec in schema.items():
        if key not in out:
            if spec.required:
                raise ScenarioError(f"missing key {where}.{key}")
            out[key] = spec.default
    return out


def _wrap(where: str, fn: Any, *args: Any, **kwargs: Any) -> Any:
    """Call a constructor that validates, re-raising its error with the scenario key."""
    try:
        return fn(*args, **kwargs)
    except (ValueError, TypeError) as exc:
        raise ScenarioError(f"{where}: {exc}") from None


def _formation(name: str, raw: Any, robots: tuple[int, ...]) -> Formation:
    where = f"formations.{name}"
    t = _table(raw, where, FORMATION_KEYS)
    n = len(robots)
    shape = t["shape"]
    if shape == "wedge":
        form = _wrap(where, wedge, n, t["lateral_m"], t["back_m"], first_id=robots[0])
    elif shape == "line":
        form = _wrap(where, line, n, t["spacing_m"], first_id=robots[0], follow=t["follow"])
    elif shape == "abreast":
        form = _wrap(where, abreast, n, t["spacing_m"], first_id=robots[0])
    elif shape == "grid":
        form = _wrap(where, grid, n, t["columns"], t["lateral_m"], t["back_m"], first_id=robots[0])
    elif shape == "custom":
        slots = {}
        for rid_text, slot in t["slots"].items():
            sw = f"{where}.slots.{rid_text}"
            if not str(rid_text).isdigit():
                raise ScenarioError(f"{sw}: slot keys are robot ids, got {rid_text!r}")
            st = _table(slot, sw, SLOT_KEYS)
            off = st["offset"]
            if len(off) != 2 or not all(isinstance(v, NUM) and not isinstance(v, bool) for v in off):
                raise ScenarioError(f"{sw}.offset must be [x_m, y_m], got {off!r}")
            slots[int(rid_text)] = Slot(st["reference"], Point(float(off[0]), float(off[1])))
        form = _wrap(where, Formation, name, slots)
    else:
        raise ScenarioError(
            f"{where}.shape must be one of {', '.join(map(repr, SHAPES))}, got {shape!r}" + _suggest(str(shape), SHAPES)
        )
    form = Formation(name, form.slots)
    if sorted(form.robots) != list(robots):
        hint = (
            (
                f'; a custom formation places the robots its slots name, a shape (e.g. {where}.shape = "wedge")'
                " places any number"
            )
            if shape == "custom"
            else ""
        )
        raise ScenarioError(
            f"{where} covers robots {id_ranges(form.robots)}, the run has robots {id_ranges(robots)}{hint}"
        )
    return form


def _check_sight(
    ld: Mapping[str, Any],
    formations: Mapping[str, Formation],
    camera: CameraParams,
    followers: Mapping[int, FollowerParams],
    forms_raw: Mapping[str, Any],
) -> None:
    """Every follower sees its reference from its slot, and at a switch between
    the leader's two formations its new reference from its old slot, with a
    margin: the fuzzy controller's dmax_m in range (a follower that far from
    its slot is at full "Far" and still sees its reference) and its heading
    tolerance gamma in the field of view (the largest of the followers')."""
    cam = Camera(
        range_m=camera.range_m,
        fov_rad=camera.fov_rad,
        marker_offset_m=camera.marker_offset_m,
        range_margin_m=max(fp.fuzzy.dmax_m for fp in followers.values()),
        fov_margin_rad=max(fp.fuzzy.gamma_rad for fp in followers.values()),
    )
    for name, form in formations.items():
        _wrap(f"formations.{name}", check_sight, form, cam)
    if ld["avoid_formation"]:
        normal, avoid = formations[ld["formation"]], formations[ld["avoid_formation"]]
        try:
            check_switch(normal, avoid, cam)
            check_switch(avoid, normal, cam)
        except ValueError as exc:
            pair = (forms_raw[ld["formation"]], forms_raw[ld["avoid_formation"]])
            lines = [
                n
                for n, t in zip((ld["formation"], ld["avoid_formation"]), pair, strict=True)
                if t.get("shape") == "line" and t.get("follow", "ahead") == "ahead"
            ]
            hint = _switch_hint(lines[0], ld["avoid_formation"]) if lines else ""
            raise ScenarioError(f"leader.avoid_formation: {exc}{hint}") from None


def _switch_hint(line: str, avoid: str) -> str:
    """The ways past a refused switch to a line that follows the robot ahead:
    the line alone (measured to hold), or the line on pairs (accepted, not safe)."""
    alone = f"--set leader.formation={line}" + ("" if avoid == line else " --set leader.avoid_formation=''")
    return (
        f"; to keep the {line!r} throughout: {alone} (with --set controller.lookahead_m=1 for a long chain; "
        f"README, 'Running things'); or a {line!r} with follow = 'pairs', which has the references of a wedge "
        f"(--set formations.{line}.follow=pairs): the switch is then accepted, but measured with 30 robots it "
        "let them touch (docs/paper.md, 'Beyond the paper: formations of many robots')"
    )


def id_ranges(ids: Sequence[int]) -> str:
    """[2, 3, 4, 7] -> "2-4, 7"."""
    runs: list[list[int]] = []
    for i in sorted(ids):
        if runs and i == runs[-1][-1] + 1:
            runs[-1].append(i)
        else:
            runs.append([i])
    return ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)


def _robots(rids: Sequence[int], one: str, many: str) -> str:
    """The words "robot 5 is" or "robots 5-9 are" (``one`` = "is", ``many`` = "are")."""
    return f"robot {rids[0]} {one}" if len(rids) == 1 else f"robots {id_ranges(rids)} {many}"


def path_turns(waypoints: Sequence[Sequence[float]]) -> bool:
    """Whether the leader's path has a corner: the robots start heading along
    its first leg (world.engine.start_poses), so a path of legs in one
    direction is flown without a turn."""
    headings = [
        math.atan2(b[1] - a[1], b[0] - a[0])
        for a, b in itertools.pairwise(waypoints)
        if math.hypot(b[0] - a[0], b[1] - a[1]) > 1e-9
    ]
    return any(abs(math.remainder(h - g, math.tau)) > 1e-9 for g, h in itertools.pairwise(headings))


def turn_warnings(speed_mps: float, turn_rate_rps: float, formations: Mapping[str, Formation]) -> list[str]:
    """The formations with slots farther to the side of the leader than its turn
    radius (speed / turn rate): in a turn toward them such a slot moves
    backwards, and a robot cannot drive backwards, so the formation folds."""
    radius = speed_mps / turn_rate_rps
    out = []
    for name, form in formations.items():
        side = {rid: abs(p.x_m) for rid, p in form.slot_positions().items() if rid != form.leader}
        beyond = sorted(rid for rid, x in side.items() if x > radius + 1e-6)
        if beyond:
            far = max(side[r] for r in beyond)
            out.append(
                f"formation {name!r}: {_robots(beyond, 'sits', 'sit')} up to {far:g} m to the side of the leader, "
                f"beyond its turn radius leader.speed_mps / leader.turn_rate_rps = {radius:g} m: in a turn toward them "
                "their slots move backwards, which the robots cannot do, and the formation folds (closer spacing, "
                "e.g. lateral_m, or a gentler turn keeps every slot inside the radius)"
            )
    return out


# From this many references down a chain the paper's steering makes a weave
# (docs/paper.md, "The steering look-ahead": in a line on a straight path,
# robot 5, four links down, swings its heading 17.3 degrees, robot 2 2.6).
CHAIN_WARN_DEPTH = 4
# The smallest look-ahead measured to keep those swings level (the same
# section: 0.5 m still let them grow, to 13.6 degrees at robot 10).
CHAIN_LOOKAHEAD_M = 1.0


def chain_warnings(formations: Mapping[str, Formation], followers: Mapping[int, FollowerParams]) -> list[str]:
    """The formations with fuzzy followers CHAIN_WARN_DEPTH or more references
    down a chain from the leader that steer at their target itself
    (controller.lookahead_m = 0), or look ahead less than CHAIN_LOOKAHEAD_M:
    each swings more than its reference."""
    out = []
    for name, form in formations.items():
        depths = form.depths()
        steers_short = {rid for rid, f in followers.items() if f.law == "fuzzy" and f.lookahead_m < CHAIN_LOOKAHEAD_M}
        deep = sorted(rid for rid, d in depths.items() if d >= CHAIN_WARN_DEPTH and rid in steers_short)
        if deep:
            low, high = min(depths[r] for r in deep), max(depths[r] for r in deep)
            # Between a follower d references down and the leader: d - 1 other robots.
            links = f"{low - 1}" if low == high else f"{low - 1}-{high - 1}"
            used = sorted({followers[r].lookahead_m for r in deep})
            if used == [0.0]:
                steering = "with the paper's steering (controller.lookahead_m = 0) heading swings grow"
            else:
                values = " and ".join(f"{v:g}" for v in used)
                steering = (
                    f"with controller.lookahead_m = {values}, under {CHAIN_LOOKAHEAD_M:g} m, heading swings still grow"
                )
            out.append(
                f"formation {name!r}: {_robots(deep, 'follows', 'follow')} the leader through a chain of "
                f'{links} other robots; {steering} at every link (docs/paper.md, "The steering look-ahead"): '
                f"--set controller.lookahead_m={CHAIN_LOOKAHEAD_M:g} keeps them level"
            )
    return out


def speed_warnings(leader_speed_mps: float, followers: Mapping[int, FollowerParams]) -> list[str]:
    """Why the leader's cruise speed lies outside the speeds its fuzzy
    followers hold steadily (agents.fuzzy.speed_range), one line per group of
    followers with the same range; empty when it lies inside every range."""
    groups: dict[tuple[str, float, float, float], list[int]] = {}
    for rid, fp in followers.items():
        if fp.law != "fuzzy":
            continue
        r = speed_range(fp.fuzzy, fp.speed)
        if leader_speed_mps < r.steady_low_mps - 1e-9:
            key = ("below", r.steady_low_mps, r.steady_high_mps, r.floor_mps)
        elif leader_speed_mps > r.steady_high_mps + 1e-9:
            key = ("above", r.steady_low_mps, r.steady_high_mps, r.ceiling_mps)
        else:
            continue
        groups.setdefault(key, []).append(rid)
    out = []
    for (side, low, high, limit), rids in groups.items():
        one = len(rids) == 1
        who = (
            f"follower {rids[0]}'s fuzzy controller holds"
            if one
            else f"followers {id_ranges(rids)}' fuzzy controllers hold"
        )
        they, their = ("it", "its") if one else ("they", "their")
        drives = ("drives" if one else "drive") + (" slower" if side == "below" else " faster")
        fate = (
            f"will overrun {their} target{'' if one else 's'} and may hit {their} reference{'' if one else 's'}"
            if side == "below"
            else f"will fall behind and may lose {their} reference{'' if one else 's'}"
        )
        out.append(
            f"leader.speed_mps = {leader_speed_mps:g} is {side} the speeds {who} steadily, {low:g}-{high:g} m/s"
            f" (vm -+ a_mps, or a static vn -+ a_mps), and {they} never {drives} than {limit:g} m/s: {they} {fate}"
        )
    return out


def _follower_params(where: str, t: Mapping[str, Any], robot: Mapping[str, Any], dt: float) -> FollowerParams:
    vn = t["vn"]
    if isinstance(vn, str):
        if vn != "dynamic":
            raise ScenarioError(f"{where}.vn must be 'dynamic' or a number, got {vn!r}")
        mode = SpeedMode()
    else:
        mode = _wrap(f"{where}.vn", SpeedMode, vn)
    fz = _wrap(
        where,
        FuzzyParams,
        gamma_rad=math.radians(t["gamma_deg"]),
        **{k: float(t[k]) for k in ("d0_m", "dn_m", "d1_m", "dmax_m", "a_mps", "vn_min", "vm", "vn_max")},
        drho_rate_tol_mps=float(t["drho_rate_tol_mps"]),
    )
    ekf_t = _table(t["ekf"], f"{where}.ekf", EKF_KEYS)
    ekf = _wrap(f"{where}.ekf", EkfParams, **{k: float(v) for k, v in ekf_t.items()})
    return _wrap(
        where,
        FollowerParams,
        width_m=float(robot["width_m"]),
        marker_offset_m=float(robot["marker_offset_m"]),
        dt_s=dt,
        clearance_m=float(t["clearance_m"]),
        lost_after_s=float(t["lost_after_s"]),
        hold_speed_mps=float(t["hold_speed_mps"]),
        resume_speed_mps=float(t["resume_speed_mps"]),
        hold_after_s=float(t["hold_after_s"]),
        wait_ahead=t["wait_ahead"],
        lookahead_m=float(t["lookahead_m"]),
        fuzzy=fz,
        speed=mode,
        ekf=ekf,
        use_ekf=t["use_ekf"],
        law=t["law"],
        drho_at_sign_change=t["drho_at_sign_change"],
        lpsi=_wrap(
            where,
            LpsiParams,
            l_gain=float(t["lpsi_l_gain"]),
            psi_gain=float(t["lpsi_psi_gain"]),
            d_m=float(t["lpsi_d_m"]),
            max_wheel_mps=fz.vn_max + fz.a_mps,
        ),
    )


def _check_wheel_limit(
    max_wheel: float, width: float, leader: Mapping[str, Any], followers: Mapping[int, FollowerParams]
) -> None:
    """Every controller's fastest wheel command within robot.max_wheel_mps: the
    world would clamp it otherwise, and the run would not fly the controller."""
    fastest = float(leader["speed_mps"]) + float(leader["turn_rate_rps"]) * width / 2.0  # eq. 8-9
    if fastest > max_wheel:
        raise ScenarioError(
            f"the leader's wheels reach {fastest:g} m/s (leader.speed_mps + leader.turn_rate_rps * robot.width_m / 2),"
            f" above robot.max_wheel_mps = {max_wheel:g}"
        )
    for rid, fp in followers.items():
        vn = fp.speed.static_vn if fp.speed.static_vn is not None else fp.fuzzy.vn_max
        if vn + fp.fuzzy.a_mps > max_wheel:
            raise ScenarioError(
                f"follower {rid}'s fuzzy controller commands up to {vn + fp.fuzzy.a_mps:g} m/s (V_N + a_mps),"
                f" above robot.max_wheel_mps = {max_wheel:g}"
            )


def from_dict(raw: Mapping[str, Any]) -> Scenario:
    if not isinstance(raw, Mapping):
        raise ScenarioError(f"a scenario must be a table, got {type(raw).__name__}")
    for key in raw:
        if key not in TOP_KEYS:
            # A key of a section given without it (robots=30 for run.robots=30): name its place.
            places = [
                f"{name}.{key}"
                for name, (schema, _, _) in SECTIONS.items()
                if "." not in name and name != "followers" and key in schema
            ]
            hint = f"; did you mean {' or '.join(map(repr, places))}?" if places else _suggest(key, TOP_KEYS)
            raise ScenarioError(f"unknown section [{key}]" + hint)
    run = _table(raw.get("run"), "run", RUN_KEYS)
    dt = float(run["dt_s"])
    duration = float(run["duration_s"])
    if round(duration / dt) < 1:  # no tick at all: a run with nothing to measure
        raise ScenarioError(f"run.duration_s: at least one control step (run.dt_s = {dt:g} s), got {duration:g}")
    n = run["robots"]
    robot = _table(raw.get("robot"), "robot", ROBOT_KEYS)
    cam = _table(raw.get("camera"), "camera", CAMERA_KEYS)
    camera = _wrap(
        "camera",
        CameraParams,
        fov_rad=math.radians(cam["fov_deg"]),
        range_m=float(cam["range_m"]),
        sigma_rho_m=float(cam["sigma_rho_m"]),
        sigma_phi_rad=math.radians(cam["sigma_phi_deg"]),
        sigma_beta_rad=math.radians(cam["sigma_beta_deg"]),
        marker_offset_m=float(robot["marker_offset_m"]),
    )
    ld = _table(raw.get("leader"), "leader", LEADER_KEYS)
    robots = tuple(range(ld["id"], ld["id"] + n))
    if not 1 <= ld["id"] <= MAX_ROBOT_ID - n + 1:
        raise ScenarioError(f"leader.id must be in [1, {MAX_ROBOT_ID - n + 1}], got {ld['id']!r}")
    wps = ld["waypoints"]
    if len(wps) < 2 or not all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(v, NUM) and not isinstance(v, bool) for v in p)
        for p in wps
    ):
        raise ScenarioError(f"leader.waypoints must be at least 2 points [x_m, y_m], got {wps!r}")
    if ld["corners"] not in CORNERS:
        raise ScenarioError(f"leader.corners must be one of {', '.join(map(repr, CORNERS))}, got {ld['corners']!r}")
    radius = float(ld["speed_mps"]) / float(ld["turn_rate_rps"])
    if problems := turn_room(wps, radius):
        raise ScenarioError(
            f"leader.waypoints: the leader cannot turn these corners at leader.speed_mps = {ld['speed_mps']:g}"
            f" and leader.turn_rate_rps = {ld['turn_rate_rps']:g} (turn radius R = {radius:.4g} m): "
            + "; ".join(problems)
        )

    forms_raw = raw.get("formations")
    if not isinstance(forms_raw, dict) or not forms_raw:
        raise ScenarioError("[formations] must hold at least one named formation")
    if len(forms_raw) > 256:
        raise ScenarioError(f"at most 256 formations, got {len(forms_raw)}")
    formations = {name: _formation(name, spec, robots) for name, spec in forms_raw.items()}
    for key in ("formation", "avoid_formation"):
        val = ld[key]
        if key == "avoid_formation" and val == "":
            continue
        if val not in formations:
            raise ScenarioError(f"leader.{key} = {val!r} is not a formation" + _suggest(val, tuple(formations)))
    for name, form in formations.items():
        if form.leader != ld["id"]:
            raise ScenarioError(f"formations.{name} is led by robot {form.leader}, leader.id is {ld['id']}")

    # [controller] is validated on its own too, even when every follower overrides it.
    _table(raw.get("controller"), "controller", CONTROLLER_KEYS)
    followers: dict[int, FollowerParams] = {}
    per = raw.get("followers", {})
    if not isinstance(per, dict):
        raise ScenarioError("[followers] must be a table of robot ids")
    follower_ids = [r for r in robots if r != ld["id"]]
    for key in per:
        if not str(key).isdigit() or int(key) not in follower_ids:
            raise ScenarioError(f"followers.{key}: not a follower id; followers are {follower_ids}")
    shared: FollowerParams | None = None  # the [controller] table's, made once for every follower without its own
    for rid in follower_ids:
        merged = dict(raw.get("controller") or {})
        override = per.get(str(rid), {})
        if not isinstance(override, dict):
            raise ScenarioError(f"followers.{rid} must be a table")
        if not override and shared is not None:
            followers[rid] = shared  # frozen: one object serves them all
            continue
        merged.update(override)
        where = f"followers.{rid}" if override else "controller"
        followers[rid] = _follower_params(where, _table(merged, where, CONTROLLER_KEYS), robot, dt)
        if not override:
            shared = followers[rid]

    _check_wheel_limit(float(robot["max_wheel_mps"]), float(robot["width_m"]), ld, followers)
    _check_sight(ld, formations, camera, followers, forms_raw)
    speed = speed_warnings(float(ld["speed_mps"]), followers)
    # Of the formations the leader flies (a scenario may hold others it never picks).
    flown = {name: formations[name] for name in (ld["formation"], ld["avoid_formation"]) if name}
    if path_turns(wps):  # a straight path folds no formation
        speed += turn_warnings(float(ld["speed_mps"]), float(ld["turn_rate_rps"]), flown)
    speed += chain_warnings(flown, followers)

    obstacles = []
    obs_raw = raw.get("obstacles", [])
    if not isinstance(obs_raw, list):
        raise ScenarioError("obstacles must be an array of tables ([[obstacles]])")
    if len(obs_raw) > MAX_OBSTACLES:
        raise ScenarioError(f"at most {MAX_OBSTACLES} obstacles, got {len(obs_raw)}")
    for i, o in enumerate(obs_raw):
        t = _table(o, f"obstacles[{i}]", OBSTACLE_KEYS)
        obstacles.append(Obstacle(float(t["x_m"]), float(t["y_m"]), float(t["radius_m"])))
    lk = _table(raw.get("links"), "links", LINK_KEYS)
    faults_raw = raw.get("faults", [])
    if not isinstance(faults_raw, list):
        raise ScenarioError("faults must be an array ([[faults]] tables or strings such as 'kill agent-3@20s')")
    try:
        faults = parse_all(faults_raw)
        check_against(faults, robots, ld["id"], duration, dt)
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    placement = _placement(raw.get("placement", {}), robots)
    sc = Scenario(
        placement=placement,
        name=run["name"],
        seed=run["seed"],
        dt_s=dt,
        duration_s=duration,
        lockstep_deadline_s=float(run["lockstep_deadline_s"]),
        stale_after_s=float(run["stale_after_s"]),
        robots=robots,
        width_m=float(robot["width_m"]),
        diameter_m=float(robot["diameter_m"]),
        max_wheel_mps=float(robot["max_wheel_mps"]),
        camera=camera,
        leader=LeaderSpec(
            robot_id=ld["id"],
            speed_mps=float(ld["speed_mps"]),
            turn_rate_rps=float(ld["turn_rate_rps"]),
            lookahead_m=float(ld["lookahead_m"]),
            corners=ld["corners"],
            waypoints=tuple((float(p[0]), float(p[1])) for p in wps),
            sensing_range_m=float(ld["sensing_range_m"]),
            formation=ld["formation"],
            avoid_formation=ld["avoid_formation"] or None,
            clear_after_s=float(ld["clear_after_s"]),
            code_burst_s=float(ld["code_burst_s"]),
            code_period_s=float(ld["code_period_s"]),
        ),
        formations=formations,
        followers=followers,
        obstacles=tuple(obstacles),
        links=LinkFaults(**{k: float(v) for k, v in lk.items()}),
        raw=raw,
        faults=faults,
        wheel_noise_mps=float(robot["wheel_noise_mps"]),
    )
    said = tuple(speed + past_the_end(faults, duration, dt))
    for text in said:  # for a library's user; swarm run prints Scenario.warnings with the run's lines
        warnings.warn(text, ScenarioWarning, stacklevel=2)
    return replace(sc, warnings=said)


def _placement(table: Any, robots: Sequence[int]) -> tuple[tuple[int, str], ...]:
    """``[placement]``: robot id = host name, for runs spread over hosts."""
    if not isinstance(table, Mapping):
        raise ScenarioError('placement must be a table of robot id = host name, e.g. [placement] 1 = "b"')
    out = []
    for key, host in table.items():
        if not str(key).isdigit() or int(key) not in robots:
            raise ScenarioError(
                f"placement: {key!r} is not a robot of this run; robots are {', '.join(map(str, robots))}"
            )
        try:
            out.append((int(key), check_host_name(host)))
        except ValueError as exc:
            raise ScenarioError(f"placement.{key}: {exc}") from None
    return tuple(sorted(out))


def load(
    path: str | Path, overrides: Mapping[str, Any] | None = None, faults: Sequence[Fault | str | Mapping[str, Any]] = ()
) -> Scenario:
    """Read a scenario (a file or a shipped scenario's name); ``overrides`` maps
    dotted keys ("run.seed") to values, checked like the file's own; ``faults``
    are added to the file's [[faults]] (as tables, so the scenario as run holds them)."""
    p = resolve(path)
    try:
        raw = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{p}: not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{p}: cannot read the scenario: {exc}") from None
    for dotted, value in (overrides or {}).items():
        raw = deep_set(raw, tuple(dotted.split(".")), value)
    if faults:
        try:
            extra = [f.to_table() for f in parse_all(faults, "fault")]
        except ValueError as exc:
            raise ScenarioError(str(exc)) from None
        old = raw.get("faults", [])
        raw = {**raw, "faults": [*(old if isinstance(old, list) else [old]), *extra]}
    try:
        return from_dict(raw)
    except ScenarioError as exc:
        # The values given beside the file (--set) are named: the error may be theirs.
        given = ", ".join(f"{k} = {json.dumps(v)}" for k, v in (overrides or {}).items())
        raise ScenarioError(f"{p}{f' (with {given})' if given else ''}: {exc}") from None
