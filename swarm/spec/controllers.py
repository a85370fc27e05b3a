"""The followers' controllers: the ``[controller]`` table every follower
takes, ``[followers.ID]`` overrides of it, and every controller's fastest
wheel command within what the robots' wheels can do.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from formation_swarm.agents.ekf import EkfParams
from formation_swarm.agents.follower import FollowerParams
from formation_swarm.agents.fuzzy import FuzzyParams, SpeedMode
from formation_swarm.agents.lpsi import LpsiParams
from formation_swarm.spec.checking import check_table, wrapped
from formation_swarm.spec.keys import CONTROLLER_KEYS, EKF_KEYS, ScenarioError


def parse_followers(
    raw: Mapping[str, Any], followers: list[int], robot: Mapping[str, Any], dt: float
) -> dict[int, FollowerParams]:
    """Each follower's controller: ``[controller]`` with its ``[followers.ID]``
    table over it; ``robot`` is the checked [robot] table."""
    # [controller] is validated on its own too, even when every follower overrides it.
    check_table(raw.get("controller"), "controller", CONTROLLER_KEYS)
    per = raw.get("followers", {})
    if not isinstance(per, dict):
        raise ScenarioError("[followers] must be a table of robot ids")
    for key in per:
        if not str(key).isdigit() or int(key) not in followers:
            raise ScenarioError(f"followers.{key}: not a follower id; followers are {followers}")
    out: dict[int, FollowerParams] = {}
    shared: FollowerParams | None = None  # the [controller] table's, made once for every follower without its own
    for rid in followers:
        merged = dict(raw.get("controller") or {})
        override = per.get(str(rid), {})
        if not isinstance(override, dict):
            raise ScenarioError(f"followers.{rid} must be a table")
        if not override and shared is not None:
            out[rid] = shared  # frozen: one object serves them all
            continue
        merged.update(override)
        where = f"followers.{rid}" if override else "controller"
        out[rid] = follower_params(where, check_table(merged, where, CONTROLLER_KEYS), robot, dt)
        if not override:
            shared = out[rid]
    return out


def follower_params(where: str, t: Mapping[str, Any], robot: Mapping[str, Any], dt: float) -> FollowerParams:
    vn = t["vn"]
    if isinstance(vn, str):
        if vn != "dynamic":
            raise ScenarioError(f"{where}.vn must be 'dynamic' or a number, got {vn!r}")
        mode = SpeedMode()
    else:
        mode = wrapped(f"{where}.vn", SpeedMode, vn)
    fz = wrapped(
        where,
        FuzzyParams,
        gamma_rad=math.radians(t["gamma_deg"]),
        **{k: float(t[k]) for k in ("d0_m", "dn_m", "d1_m", "dmax_m", "a_mps", "vn_min", "vm", "vn_max")},
        drho_rate_tol_mps=float(t["drho_rate_tol_mps"]),
    )
    ekf_t = check_table(t["ekf"], f"{where}.ekf", EKF_KEYS)
    ekf = wrapped(f"{where}.ekf", EkfParams, **{k: float(v) for k, v in ekf_t.items()})
    return wrapped(
        where,
        FollowerParams,
        width_m=float(robot["width_m"]),
        marker_offset_m=float(robot["marker_offset_m"]),
        dt_s=dt,
        clearance_m=float(t["clearance_m"]),
        avoidance=t["avoidance"],
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
        lpsi=wrapped(
            where,
            LpsiParams,
            l_gain=float(t["lpsi_l_gain"]),
            psi_gain=float(t["lpsi_psi_gain"]),
            d_m=float(t["lpsi_d_m"]),
            max_wheel_mps=fz.vn_max + fz.a_mps,
        ),
    )


def check_wheel_limit(
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
