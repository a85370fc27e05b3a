"""The followers' controllers: the ``[controller]`` table every follower
takes, ``[followers.ID]`` overrides of it, the law each flies with its
``params`` checked against the law's class (agents.laws), and every
controller's fastest wheel command within what the robots' wheels can do.
The leader's policy (``leader.policy``, ``[leader.params]``) is checked the
same way.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from formation_swarm.agents.ekf import EkfParams
from formation_swarm.agents.follower import LAWS, FollowerParams, law_class
from formation_swarm.agents.fuzzy import FuzzyParams, SpeedMode
from formation_swarm.agents.laws import FOLLOWER, LEADER, PATH, Kind, LawError, declared_params
from formation_swarm.agents.leader_policy import policy_class
from formation_swarm.agents.lpsi import LpsiParams
from formation_swarm.spec.checking import check_table, check_times, wrapped
from formation_swarm.spec.keys import CONTROLLER_KEYS, EKF_KEYS, NUM, Key, ScenarioError


def parse_followers(
    raw: Mapping[str, Any], followers: list[int], robot: Mapping[str, Any], dt: float
) -> dict[int, FollowerParams]:
    """Each follower's controller: ``[controller]`` with its ``[followers.ID]``
    table over it; ``robot`` is the checked [robot] table."""
    # [controller] is validated on its own too, even when every follower overrides it.
    check_times("controller", check_table(raw.get("controller"), "controller", CONTROLLER_KEYS), CONTROLLER_KEYS, dt)
    per = raw.get("followers", {})
    if not isinstance(per, dict):
        raise ScenarioError("[followers] must be a table of robot ids")
    for key in per:
        if not str(key).isdigit() or int(key) not in followers:
            message = f"followers.{key}: not a follower id; followers are {followers}"
            raise ScenarioError(message, key=f"followers.{key}", value=per[key])
    out: dict[int, FollowerParams] = {}
    shared: FollowerParams | None = None  # the [controller] table's, made once for every follower without its own
    for rid in followers:
        override = per.get(str(rid), {})
        if not isinstance(override, dict):
            raise ScenarioError(f"followers.{rid} must be a table")
        if not override and shared is not None:
            out[rid] = shared  # frozen: one object serves them all
            continue
        merged = with_override(raw.get("controller") or {}, override)
        where = f"followers.{rid}" if override else "controller"
        table = check_table(merged, where, CONTROLLER_KEYS)
        check_times(where, table, CONTROLLER_KEYS, dt)
        out[rid] = follower_params(where, table, robot, dt)
        if not override:
            shared = out[rid]
    return out


def follower_params(where: str, t: Mapping[str, Any], robot: Mapping[str, Any], dt: float) -> FollowerParams:
    vn = t["vn"]
    if isinstance(vn, str):
        if vn != "dynamic":
            raise ScenarioError(f"{where}.vn must be 'dynamic' or a number, got {vn!r}")
        mode = SpeedMode()
    elif vn <= 0:  # SpeedMode's own check would name its field, static_vn
        raise ScenarioError(f"{where}.vn must be 'dynamic' or a number > 0, got {vn!r}", key=f"{where}.vn", value=vn)
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
        **law_and_params(where, t),
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
    # A user's policy keeps within the limit itself (LeaderSetup.max_wheel_mps).
    if leader.get("policy", PATH) == PATH and fastest > max_wheel:
        raise ScenarioError(
            f"the leader's wheels reach {fastest:g} m/s (leader.speed_mps + leader.turn_rate_rps * robot.width_m / 2),"
            f" above robot.max_wheel_mps = {max_wheel:g}"
        )
    for rid, fp in followers.items():
        if fp.law not in LAWS:
            continue  # a user's law keeps within the limit itself (ControllerSetup.max_wheel_mps)
        vn = fp.speed.static_vn if fp.speed.static_vn is not None else fp.fuzzy.vn_max
        if vn + fp.fuzzy.a_mps > max_wheel:
            raise ScenarioError(
                f"follower {rid}'s fuzzy controller commands up to {vn + fp.fuzzy.a_mps:g} m/s (V_N + a_mps),"
                f" above robot.max_wheel_mps = {max_wheel:g}"
            )


# -- the law each follower flies, and its own parameters (docs/controllers.md) --------


def with_override(base: Mapping[str, Any], override: Mapping[str, Any]) -> dict[str, Any]:
    """``[controller]`` with a ``[followers.ID]`` table over it. Its ``params``
    go over those of [controller] name by name while it flies the same law;
    a follower that flies another law takes only its own."""
    if not isinstance(base, Mapping):
        return dict(override)  # check_table says what is wrong with [controller]
    merged = {**base, **override}
    default_law = CONTROLLER_KEYS["law"].default
    if override.get("law", base.get("law", default_law)) != base.get("law", default_law):
        merged["params"] = override.get("params", {})
    elif isinstance(base.get("params"), dict) and isinstance(override.get("params"), dict):
        merged["params"] = {**base["params"], **override["params"]}
    return merged


def law_and_params(where: str, t: Mapping[str, Any]) -> dict[str, Any]:
    """``law`` and ``params`` of a checked controller table, as FollowerParams
    takes them: the law's class found (imported) and its params checked against
    what it declares, each filled with its default, before any process starts."""
    law = t["law"]
    own = " (its parameters are the keys of [controller])" if law in LAWS else ""
    return {"law": law, "law_params": _params(where, t["params"], kind=FOLLOWER, name=law, own=own)}


def policy_and_params(t: Mapping[str, Any]) -> dict[str, Any]:
    """``policy`` and ``params`` of the checked [leader] table, as
    agents.leader_policy.LeaderParams takes them, checked as a law's are."""
    policy = t["policy"]
    own = " (its parameters are the keys of [leader])" if policy == PATH else ""
    return {"policy": policy, "policy_params": _params("leader", t["params"], kind=LEADER, name=policy, own=own)}


def _params(where: str, given: Mapping[str, Any], *, kind: Kind, name: str, own: str) -> tuple[tuple[str, Any], ...]:
    """The params ``given`` to the class ``name`` names (a law, a policy: ``kind``),
    checked against what it declares; ``own``: where a class without any takes its own."""
    try:
        declared = declared_params((law_class if kind is FOLLOWER else policy_class)(name), name, kind)
    except LawError as exc:
        raise ScenarioError(f"{where}.{kind.word}: {exc}") from None
    if given and not declared:
        first = next(iter(given))
        raise ScenarioError(f"unknown key {where}.params.{first}: {kind.word} {name!r} takes no params{own}")
    schema = {n: _param_key(default) for n, default in declared.items()}
    checked = check_table(given, f"{where}.params", schema)
    # A float parameter given as an integer (gain = 2, --set ...=1,2,3) is the float.
    return tuple((k, float(v) if isinstance(declared[k], float) else v) for k, v in checked.items())


def _param_key(default: bool | int | float | str) -> Key:
    """The key a declared parameter is checked with: its default's type (an
    integer is a number where the default is a float)."""
    kind = NUM if isinstance(default, float) else type(default)
    return Key(kind, default, "")
