"""Scenario files (TOML): robots, formations, the leader's path, obstacles,
noise, controller parameters, link faults, seed, dt and duration.

A scenario is named by a path to its file or by the name of a shipped one
(``fig11_obstacles``: ``scenarios/*.toml``, installed with the package).
Unknown keys are errors that name the key and suggest the closest valid one;
invalid values are errors that name the key and the value.

This module reads a file into a :class:`Scenario` (``spec.model``), table by
table: the formations are ``spec.formations``', the followers' controllers
``spec.controllers``', the warnings ``spec.caveats``'.
"""

from __future__ import annotations

import json
import math
import tomllib
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from formation_swarm.agents.pilot import CORNERS, turn_room
from formation_swarm.common.faults import Fault, parse_all
from formation_swarm.common.faults.schedule import check_against
from formation_swarm.protocol.keys import MAX_ROBOT_ID, check_host_name
from formation_swarm.spec.caveats import path_turns
from formation_swarm.spec.checking import (
    check_name,
    check_table,
    check_times,
    check_values,
    id_ranges,
    is_point,
    suggest,
    wrapped,
)
from formation_swarm.spec.controllers import check_wheel_limit, parse_followers, policy_and_params
from formation_swarm.spec.files import deep_set, resolve
from formation_swarm.spec.formations import check_in_sight, parse_formations
from formation_swarm.spec.keys import (
    CAMERA_KEYS,
    LEADER_KEYS,
    LINK_KEYS,
    MAX_DEPTH,
    MAX_OBSTACLES,
    OBSTACLE_KEYS,
    ROBOT_KEYS,
    RUN_KEYS,
    SECTIONS,
    TOP_KEYS,
    ScenarioError,
    ScenarioWarning,
)
from formation_swarm.spec.model import LeaderSpec, LinkFaults, Obstacle, Scenario
from formation_swarm.spec.ros2 import ros2_settings
from formation_swarm.world.camera import CameraParams

# What the package's other layers and a library's user take from here.
__all__ = [
    "LeaderSpec",
    "LinkFaults",
    "Obstacle",
    "Scenario",
    "ScenarioError",
    "ScenarioWarning",
    "from_dict",
    "id_ranges",
    "load",
    "path_turns",
]


def from_dict(raw: Mapping[str, Any]) -> Scenario:
    """A scenario from its TOML tables, each checked in the order it is read."""
    _check_sections(raw)
    check_values(raw)
    run = _run(raw.get("run"))
    dt = float(run["dt_s"])
    robot = check_table(raw.get("robot"), "robot", ROBOT_KEYS)
    camera = _camera(raw.get("camera"), robot)
    ld = _leader(raw.get("leader"), run["robots"])
    check_times("leader", ld, LEADER_KEYS, dt)
    robots = tuple(range(ld["id"], ld["id"] + run["robots"]))
    formations = parse_formations(raw.get("formations"), robots, ld)
    followers = parse_followers(raw, [r for r in robots if r != ld["id"]], robot, dt)
    check_wheel_limit(float(robot["max_wheel_mps"]), float(robot["width_m"]), ld, followers)
    check_in_sight(ld, formations, camera, followers, raw["formations"])
    obstacles = _obstacles(raw.get("obstacles", []))
    links = check_table(raw.get("links"), "links", LINK_KEYS)
    ros2_settings(raw)  # checked with the rest; swarm run --ros2 reads it (spec.ros2)
    faults = _faults(raw.get("faults", []), robots, ld["id"], run)
    sc = Scenario(
        placement=_placement(raw.get("placement", {}), robots),
        name=run["name"],
        seed=run["seed"],
        dt_s=dt,
        duration_s=float(run["duration_s"]),
        lockstep_deadline_s=float(run["lockstep_deadline_s"]),
        stale_after_s=float(run["stale_after_s"]),
        robots=robots,
        width_m=float(robot["width_m"]),
        diameter_m=float(robot["diameter_m"]),
        max_wheel_mps=float(robot["max_wheel_mps"]),
        camera=camera,
        leader=_leader_spec(ld),
        formations=formations,
        followers=followers,
        obstacles=obstacles,
        links=LinkFaults(**{k: float(v) for k, v in links.items()}),
        raw=raw,
        faults=faults,
        wheel_noise_mps=float(robot["wheel_noise_mps"]),
    )
    for text in sc.warnings:  # for a library's user; swarm run prints Scenario.warnings with the run's lines
        warnings.warn(text, ScenarioWarning, stacklevel=2)
    return sc


def _check_sections(raw: Any) -> None:
    """A table of known sections; a key of a section given without it is named in its place."""
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
            hint = f"; did you mean {' or '.join(map(repr, places))}?" if places else suggest(key, TOP_KEYS)
            raise ScenarioError(f"unknown section [{key}]" + hint)


def _run(raw: Any) -> dict[str, Any]:
    """``[run]``, with at least one tick and no more than a message counts; a
    name the run's id and folder are made of."""
    run = check_table(raw, "run", RUN_KEYS)
    dt, duration = float(run["dt_s"]), float(run["duration_s"])
    if round(duration / dt) < 1:  # no tick at all: a run with nothing to measure
        raise ScenarioError(
            f"run.duration_s: at least one control step (run.dt_s = {dt:g} s), got {duration:g}",
            key="run.duration_s",
            value=run["duration_s"],
        )
    check_times("run", run, RUN_KEYS, dt)
    name = run["name"]
    check_name("run.name", name)
    # launch.plan makes the run's id of the name's letters, digits, '-' and '_' (any other
    # character a '-'), and the id names the run's Zenoh keys (protocol.keys): ASCII only.
    if any(ch.isalnum() and not ch.isascii() for ch in name):
        raise ScenarioError(
            f"run.name must write its letters and digits in ASCII (the run's id and folder are made of them;"
            f" other characters become '-'), got {name!r}",
            key="run.name",
            value=name,
        )
    return run


def _camera(raw: Any, robot: Mapping[str, Any]) -> CameraParams:
    """``[camera]``, its angles in radians; the marker's place is the robot's."""
    cam = check_table(raw, "camera", CAMERA_KEYS)
    return wrapped(
        "camera",
        CameraParams,
        fov_rad=math.radians(cam["fov_deg"]),
        range_m=float(cam["range_m"]),
        sigma_rho_m=float(cam["sigma_rho_m"]),
        sigma_phi_rad=math.radians(cam["sigma_phi_deg"]),
        sigma_beta_rad=math.radians(cam["sigma_beta_deg"]),
        marker_offset_m=float(robot["marker_offset_m"]),
    )


def _leader(raw: Any, n: int) -> dict[str, Any]:
    """``[leader]``: an id that leaves room for ``n`` robots, a path it can fly."""
    ld = check_table(raw, "leader", LEADER_KEYS)
    if not 1 <= ld["id"] <= MAX_ROBOT_ID - n + 1:
        raise ScenarioError(f"leader.id must be in [1, {MAX_ROBOT_ID - n + 1}], got {ld['id']!r}")
    wps = ld["waypoints"]
    if len(wps) < 2 or not all(is_point(p) for p in wps):
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
    return ld


def _leader_spec(ld: Mapping[str, Any]) -> LeaderSpec:
    return LeaderSpec(
        robot_id=ld["id"],
        speed_mps=float(ld["speed_mps"]),
        turn_rate_rps=float(ld["turn_rate_rps"]),
        lookahead_m=float(ld["lookahead_m"]),
        corners=ld["corners"],
        waypoints=tuple((float(p[0]), float(p[1])) for p in ld["waypoints"]),
        sensing_range_m=float(ld["sensing_range_m"]),
        formation=ld["formation"],
        avoid_formation=ld["avoid_formation"] or None,
        clear_after_s=float(ld["clear_after_s"]),
        code_burst_s=float(ld["code_burst_s"]),
        code_period_s=float(ld["code_period_s"]),
        **policy_and_params(ld),
    )


def _obstacles(raw: Any) -> tuple[Obstacle, ...]:
    """``[[obstacles]]``, at most MAX_OBSTACLES."""
    if not isinstance(raw, list):
        raise ScenarioError("obstacles must be an array of tables ([[obstacles]])")
    if len(raw) > MAX_OBSTACLES:
        raise ScenarioError(f"at most {MAX_OBSTACLES} obstacles, got {len(raw)}")
    out = []
    for i, o in enumerate(raw):
        t = check_table(o, f"obstacles[{i}]", OBSTACLE_KEYS)
        out.append(Obstacle(float(t["x_m"]), float(t["y_m"]), float(t["radius_m"])))
    return tuple(out)


def _faults(raw: Any, robots: Sequence[int], leader_id: int, run: Mapping[str, Any]) -> tuple[Fault, ...]:
    """``[[faults]]``: the schedule, by start time, each fault one this run can take."""
    if not isinstance(raw, list):
        raise ScenarioError("faults must be an array ([[faults]] tables or strings such as 'kill agent-3@20s')")
    try:
        faults = parse_all(raw)
        check_against(faults, robots, leader_id, float(run["duration_s"]), float(run["dt_s"]))
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    return faults


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
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{p}: cannot read the scenario: {exc}") from None
    except RecursionError:  # tomllib recurses once per level of arrays and inline tables
        raise ScenarioError(f"{p}: arrays or inline tables nested more than {MAX_DEPTH} deep") from None
    except ValueError as exc:  # TOMLDecodeError, or an integer of more digits than Python reads
        raise ScenarioError(f"{p}: not valid TOML: {exc}") from None
    for dotted, value in (overrides or {}).items():
        if dotted.count(".") >= MAX_DEPTH:  # each part a table inside the one before
            raise ScenarioError(f"{p}: {dotted[:40]!r}...: a key of at most {MAX_DEPTH} parts", key=dotted)
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
        given = ", ".join(f"{k} = {_given(v)}" for k, v in (overrides or {}).items())
        raise ScenarioError(f"{p}{f' (with {given})' if given else ''}: {exc}", key=exc.key, value=exc.value) from None


def _given(value: Any) -> str:
    """A value given beside the file as an error quotes it: as JSON, its start if it is long."""
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (RecursionError, TypeError, ValueError):  # too deep, not JSON, an integer of too many digits
        return f"a {type(value).__name__}"
    return text if len(text) <= 200 else f"{text[:100]}... ({len(text)} characters)"
