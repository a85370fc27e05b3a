"""The name of the law each follower flies and of the leader's policy: one
record, ``{"leader": "path", "followers": {"2": "fuzzy (V_N dynamic)", ...}}``,
for the summary's ``laws``, the console, the report and ``swarm compare``.

A follower's law is named as ``controller.law`` names it ("lpsi",
"pkg.module:Class", an entry point's name), the paper's fuzzy law with its
V_N: "fuzzy (V_N dynamic)" or "fuzzy (V_N 1.5 m/s)". The leader's policy is
named as ``leader.policy`` names it: "path" (the paper's path follower,
agents.leader_policy.PathLeader, the default), "pkg.module:Class", an entry
point's name.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

from formation_swarm.spec.controllers import with_override
from formation_swarm.spec.keys import CONTROLLER_KEYS, LEADER_KEYS

if TYPE_CHECKING:
    from formation_swarm.agents.follower import FollowerParams
    from formation_swarm.spec.model import Scenario

LEADER_POLICY = LEADER_KEYS["policy"].default  # "path": agents.leader_policy.PathLeader, unless leader.policy says
FUZZY = "fuzzy"  # the paper's law: its name says its V_N


def law_name(law: str, vn: object) -> str:
    """A follower's law by the name ``controller.law`` gives it, the fuzzy
    law's with its V_N (``controller.vn``: "dynamic" or a speed, m/s)."""
    if law != FUZZY:
        return law
    speed = f"{vn:g} m/s" if isinstance(vn, (int, float)) and not isinstance(vn, bool) else str(vn)
    return f"{FUZZY} (V_N {speed})"


def follower_law(fp: FollowerParams) -> str:
    """The law a follower's checked parameters fly, by name (law_name)."""
    return law_name(fp.law, "dynamic" if fp.speed.static_vn is None else fp.speed.static_vn)


def laws(sc: Scenario) -> dict[str, Any]:
    """The leader's policy and each follower's law (by its id, a string as
    in the summary's ``followers``), in the order of the ids."""
    named = {str(r): follower_law(sc.followers[r]) for r in sorted(sc.followers)}
    return {"leader": sc.leader.policy, "followers": named}


def laws_as_run(config: Mapping[str, Any], followers: Iterable[int]) -> dict[str, Any]:
    """``laws`` read from a scenario as run (its TOML's tables, not checked:
    a user's law is named, not imported), for ``followers``."""
    base = config.get("controller")
    base = base if isinstance(base, Mapping) else {}
    per = config.get("followers")
    per = per if isinstance(per, Mapping) else {}
    named = {}
    for rid in sorted(followers):
        own = per.get(str(rid))
        table = with_override(base, own if isinstance(own, Mapping) else {})
        law = table.get("law", CONTROLLER_KEYS["law"].default)
        named[str(rid)] = law_name(str(law), table.get("vn", CONTROLLER_KEYS["vn"].default))
    leader = config.get("leader")
    policy = leader.get("policy", LEADER_POLICY) if isinstance(leader, Mapping) else LEADER_POLICY
    return {"leader": str(policy), "followers": named}


def run_laws(summary: Mapping[str, Any], config: Mapping[str, Any], followers: Iterable[int]) -> dict[str, Any]:
    """A run's laws: its summary's ``laws``, or for a summary written before
    it had them, ``laws_as_run`` of its scenario as run."""
    said = summary.get("laws")
    if isinstance(said, Mapping) and isinstance(said.get("followers"), Mapping):
        return {"leader": str(said.get("leader")), "followers": {str(k): str(v) for k, v in said["followers"].items()}}
    return laws_as_run(config, followers)
