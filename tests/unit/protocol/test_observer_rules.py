"""The read-only login, without a network: what its grants and router rules
allow (tests/system/test_external.py checks a router enforces them)."""

from __future__ import annotations

from pathlib import Path

from formation_swarm.protocol import acl, trust
from formation_swarm.protocol.acl import Grants

ROBOTS = (1, 2, 3)
R = "swarm/r1"


def test_the_observer_may_hear_the_whole_run_and_nothing_else() -> None:
    g = acl.grants("r1", ROBOTS, leader_id=1, observer=True)
    assert g[acl.OBSERVER] == Grants(subscribe=(f"{R}/**",), withheld=(f"{R}/robot/wake/cmd",), watch=(f"{R}/**",))
    assert acl.OBSERVER not in acl.grants("r1", ROBOTS, leader_id=1)  # only on request


def test_its_router_rules_allow_no_put_no_token_no_query_but_liveliness() -> None:
    access = acl.access_control("r1", ROBOTS, leader_id=1, observer=True)
    policy = next(p for p in access["policies"] if p["id"] == acl.OBSERVER)
    rules = {r["id"]: r for r in access["rules"]}
    assert policy == {
        "id": acl.OBSERVER,
        "rules": [
            "learn-subscribers",
            "observer-sub",
            "observer-data",
            "observer-withheld",
            "observer-watch",
            "observer-seen",
        ],
        "subjects": [acl.OBSERVER],
    }
    got = [(r["permission"], r["flows"], r["messages"], r["key_exprs"]) for r in map(rules.get, policy["rules"][1:])]
    assert got == [
        ("allow", ["ingress"], ["declare_subscriber"], [f"{R}/**"]),
        ("allow", ["egress"], ["put"], [f"{R}/**"]),
        ("deny", ["egress"], ["put"], [f"{R}/robot/wake/cmd"]),
        ("allow", ["ingress"], ["declare_liveliness_subscriber", "liveliness_query"], [f"{R}/**"]),
        ("allow", ["egress"], ["liveliness_token", "reply"], [f"{R}/**"]),
    ]
    # What it sends the router (ingress) is declarations and liveliness queries only: no data.
    sent = {m for r in policy["rules"] if rules[r]["flows"] == ["ingress"] for m in rules[r]["messages"]}
    assert sent == {"declare_subscriber", "declare_liveliness_subscriber", "liveliness_query"}
    assert {"id": acl.OBSERVER, "usernames": [acl.OBSERVER]} in access["subjects"]


def test_a_runs_secrets_hold_its_login_on_request(tmp_path: Path) -> None:
    files = trust.write_run_secrets(tmp_path / "s", "r1", ROBOTS, 1, observer=True)
    assert trust.login_user(trust.read_settings(files[acl.OBSERVER])) == acl.OBSERVER
    assert f"{acl.OBSERVER}:" in (tmp_path / "s" / trust.PASSWORDS).read_text()
    assert acl.OBSERVER not in trust.write_run_secrets(tmp_path / "t", "r1", ROBOTS, 1)
