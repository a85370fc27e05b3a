"""What an observer's router rules let through, by Zenoh's own key-expression
inclusion: the key expressions a user watches tokens with are within its
grant, and the world's wake-up key is denied although its subscription
covers it (tests/system/test_observer_keys.py checks a router)."""

from __future__ import annotations

import pytest
import zenoh

from formation_swarm.protocol import acl
from formation_swarm.protocol.keys import Keys

K = Keys("r1")


def _observer_rules() -> dict[str, dict[str, object]]:
    access = acl.access_control("r1", (1, 2, 3), leader_id=1, observer=True)
    policy = next(p for p in access["policies"] if p["id"] == acl.OBSERVER)
    rules = {r["id"]: r for r in access["rules"]}
    return {r: rules[r] for r in policy["rules"]}


def _within(key: str, granted: object) -> bool:
    """The router grants a declaration whose key expression some granted one includes."""
    assert isinstance(granted, list)
    return any(zenoh.KeyExpr(g).includes(zenoh.KeyExpr(key)) for g in granted)


@pytest.mark.parametrize("watched", ["r1/alive/**", "r1/alive/*/*", "r1/alive/agent/*", "r1/alive/world/0", "r1/**"])
def test_every_liveliness_expression_of_the_run_is_within_the_observers_grant(watched: str) -> None:
    rule = _observer_rules()["observer-watch"]
    assert rule["messages"] == ["declare_liveliness_subscriber", "liveliness_query"]
    assert _within(f"swarm/{watched}", rule["key_exprs"])


def test_the_wake_up_key_is_denied_to_the_observer_though_its_subscription_covers_it() -> None:
    rules = _observer_rules()
    data, withheld = rules["observer-data"], rules["observer-withheld"]
    assert (data["permission"], withheld["permission"]) == ("allow", "deny")  # a deny rule wins over an allow
    assert data["flows"] == withheld["flows"] == ["egress"]
    assert data["messages"] == withheld["messages"] == ["put"]
    assert _within(K.world_wake, data["key_exprs"])
    assert withheld["key_exprs"] == [K.world_wake]
    # Nothing else the run puts is withheld: each robot's observation and command still reaches it.
    for key in (K.obs(2), K.cmd(2), K.telemetry(3), K.truth, K.status, K.faults):
        assert not _within(key, withheld["key_exprs"]), key


def test_no_role_but_the_world_itself_and_the_observer_may_be_handed_the_wake_up() -> None:
    access = acl.access_control("r1", (1, 2, 3), leader_id=1, observer=True)
    handed = [
        r["id"]
        for r in access["rules"]
        if r["permission"] == "allow" and "put" in r["messages"] and r["flows"] == ["egress"]
        if _within(K.world_wake, r["key_exprs"])
    ]
    # The world's own put never comes back to it; observer-withheld denies it the observer.
    assert handed == ["world-data", "observer-data"]
