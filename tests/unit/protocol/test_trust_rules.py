"""Who may say what, without a network: the exact grants and router rules of a
run, the credential rules, and the permissions of the files that hold them
(tests/system/test_trust.py checks that a router enforces the rules)."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from formation_swarm.protocol import acl, trust
from formation_swarm.protocol.acl import Grants
from formation_swarm.protocol.trust import Credential

ROBOTS = (1, 2, 3)
R = "swarm/r1"  # the key prefix of run "r1"
WATCHING = ["declare_liveliness_subscriber", "liveliness_query"]
SEEN = ["liveliness_token", "reply"]


def _mode(path: Path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


# -- the grants and the router's rules ------------------------------------------------


def test_the_grants_of_a_three_robot_run() -> None:
    g = acl.grants("r1", ROBOTS, leader_id=1)
    assert list(g) == ["world", "logger", "launcher", "agent-1", "agent-2", "agent-3"]
    assert g["world"] == Grants(
        publish=(
            f"{R}/robot/1/obs",
            f"{R}/robot/2/obs",
            f"{R}/robot/3/obs",
            f"{R}/world/truth",
            f"{R}/world/status",
            f"{R}/world/faults",
            f"{R}/robot/wake/cmd",
        ),
        subscribe=(f"{R}/robot/*/cmd",),
        tokens=(f"{R}/alive/world/0",),
        watch=(f"{R}/alive/*/*",),
    )
    assert g["logger"] == Grants(
        subscribe=(f"{R}/world/**", f"{R}/robot/*/telemetry", f"{R}/robot/*/formation"),  # codes: the leader's switches
        tokens=(f"{R}/alive/logger/0",),
        watch=(f"{R}/alive/world/0", f"{R}/alive/agent/*"),  # the agents': a follower gone sends no more
    )
    # The launcher hears the run's status and the world's fault calls, and holds a token of its own.
    assert g["launcher"] == Grants(
        subscribe=(f"{R}/world/status", f"{R}/world/faults"),
        tokens=(f"{R}/alive/launcher/0",),
        watch=(f"{R}/alive/*/*",),
    )
    # Only the leader may publish formation codes, on one key for all its followers.
    assert g["agent-1"] == Grants(
        publish=(f"{R}/robot/1/cmd", f"{R}/robot/1/telemetry", f"{R}/robot/*/formation"),
        subscribe=(f"{R}/robot/1/*", f"{R}/world/status"),
        tokens=(f"{R}/alive/agent/1",),
        watch=(f"{R}/alive/world/0", f"{R}/alive/agent/1", f"{R}/alive/logger/0"),
    )
    for rid in (2, 3):
        assert g[f"agent-{rid}"] == Grants(
            publish=(f"{R}/robot/{rid}/cmd", f"{R}/robot/{rid}/telemetry"),
            subscribe=(f"{R}/robot/{rid}/*", f"{R}/world/status"),
            receive=(f"{R}/robot/*/formation",),  # the leader's codes, which its inbox matches
            tokens=(f"{R}/alive/agent/{rid}",),
            watch=(f"{R}/alive/world/0", f"{R}/alive/agent/{rid}", f"{R}/alive/logger/0"),
        )


@pytest.mark.parametrize("leader", ROBOTS)
def test_whoever_leads_only_the_leader_publishes_formation_codes(leader: int) -> None:
    g = acl.grants("r1", ROBOTS, leader_id=leader)
    codes = {user: [key for key in grants.publish if key.endswith("/formation")] for user, grants in g.items()}
    followers = [r for r in ROBOTS if r != leader]
    expected = {"world": [], "logger": [], "launcher": []}
    expected |= {f"agent-{r}": ([f"{R}/robot/*/formation"] if r == leader else []) for r in ROBOTS}
    assert codes == expected
    receivers = [user for user, grants in g.items() if grants.receive]
    assert receivers == [f"agent-{f}" for f in followers]


def test_robot_ids_above_256_are_compared_by_value() -> None:
    """Ids up to 10000: equal ids need not be the same int object."""
    robots = [int(s) for s in ("1001", "1002")]
    leader = int("1001")
    assert leader is not robots[0]
    g = acl.grants("r1", robots, leader_id=leader)
    assert g["agent-1001"].publish == (f"{R}/robot/1001/cmd", f"{R}/robot/1001/telemetry", f"{R}/robot/*/formation")
    assert g["agent-1002"].publish == (f"{R}/robot/1002/cmd", f"{R}/robot/1002/telemetry")


def test_the_router_rules_of_a_two_robot_run() -> None:
    """Deny by default; each user allowed exactly its grants, flow by flow."""
    rows = {  # user -> (rule, flow, messages, keys)
        "world": [
            (
                "put",
                "ingress",
                ["put"],
                [
                    f"{R}/robot/1/obs",
                    f"{R}/robot/2/obs",
                    f"{R}/world/truth",
                    f"{R}/world/status",
                    f"{R}/world/faults",
                    f"{R}/robot/wake/cmd",
                ],
            ),
            ("sub", "ingress", ["declare_subscriber"], [f"{R}/robot/*/cmd"]),
            ("data", "egress", ["put"], [f"{R}/robot/*/cmd"]),
            ("token", "ingress", ["liveliness_token"], [f"{R}/alive/world/0"]),
            ("watch", "ingress", WATCHING, [f"{R}/alive/*/*"]),
            ("seen", "egress", SEEN, [f"{R}/alive/*/*"]),
        ],
        "logger": [
            (
                "sub",
                "ingress",
                ["declare_subscriber"],
                [f"{R}/world/**", f"{R}/robot/*/telemetry", f"{R}/robot/*/formation"],
            ),
            ("data", "egress", ["put"], [f"{R}/world/**", f"{R}/robot/*/telemetry", f"{R}/robot/*/formation"]),
            ("token", "ingress", ["liveliness_token"], [f"{R}/alive/logger/0"]),
            ("watch", "ingress", WATCHING, [f"{R}/alive/world/0", f"{R}/alive/agent/*"]),
            ("seen", "egress", SEEN, [f"{R}/alive/world/0", f"{R}/alive/agent/*"]),
        ],
        "launcher": [
            ("sub", "ingress", ["declare_subscriber"], [f"{R}/world/status", f"{R}/world/faults"]),
            ("data", "egress", ["put"], [f"{R}/world/status", f"{R}/world/faults"]),
            ("token", "ingress", ["liveliness_token"], [f"{R}/alive/launcher/0"]),
            ("watch", "ingress", WATCHING, [f"{R}/alive/*/*"]),
            ("seen", "egress", SEEN, [f"{R}/alive/*/*"]),
        ],
        "agent-1": [
            ("put", "ingress", ["put"], [f"{R}/robot/1/cmd", f"{R}/robot/1/telemetry", f"{R}/robot/*/formation"]),
            ("sub", "ingress", ["declare_subscriber"], [f"{R}/robot/1/*", f"{R}/world/status"]),
            ("data", "egress", ["put"], [f"{R}/robot/1/*", f"{R}/world/status"]),
            ("token", "ingress", ["liveliness_token"], [f"{R}/alive/agent/1"]),
            ("watch", "ingress", WATCHING, [f"{R}/alive/world/0", f"{R}/alive/agent/1", f"{R}/alive/logger/0"]),
            ("seen", "egress", SEEN, [f"{R}/alive/world/0", f"{R}/alive/agent/1", f"{R}/alive/logger/0"]),
        ],
        "agent-2": [
            ("put", "ingress", ["put"], [f"{R}/robot/2/cmd", f"{R}/robot/2/telemetry"]),
            ("sub", "ingress", ["declare_subscriber"], [f"{R}/robot/2/*", f"{R}/world/status"]),
            ("data", "egress", ["put"], [f"{R}/robot/2/*", f"{R}/world/status", f"{R}/robot/*/formation"]),
            ("token", "ingress", ["liveliness_token"], [f"{R}/alive/agent/2"]),
            ("watch", "ingress", WATCHING, [f"{R}/alive/world/0", f"{R}/alive/agent/2", f"{R}/alive/logger/0"]),
            ("seen", "egress", SEEN, [f"{R}/alive/world/0", f"{R}/alive/agent/2", f"{R}/alive/logger/0"]),
        ],
    }
    learn = {
        "id": "learn-subscribers",
        "permission": "allow",
        "flows": ["egress"],
        "messages": ["declare_subscriber"],
        "key_exprs": [f"{R}/**"],
    }
    rules = [learn] + [
        {"id": f"{user}-{rule}", "permission": "allow", "flows": [flow], "messages": messages, "key_exprs": keys}
        for user, own in rows.items()
        for rule, flow, messages, keys in own
    ]
    assert acl.access_control("r1", (1, 2), leader_id=1) == {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": [{"id": user, "usernames": [user]} for user in rows],
        "policies": [
            {"id": user, "rules": ["learn-subscribers", *(f"{user}-{r[0]}" for r in own)], "subjects": [user]}
            for user, own in rows.items()
        ],
    }


# -- credentials ------------------------------------------------------------------------


@pytest.mark.parametrize("user", ["a", "agent-1", "logger", "a" + "b0-" * 10 + "c"])
def test_user_names_taken(user: str) -> None:
    assert Credential(user, "x" * 16).user == user


@pytest.mark.parametrize("user", ["", "a" * 33, "Agent-1", "1agent", "-agent", "agent_1", "agent 1", None, 7, b"agent"])
def test_user_names_refused(user: object) -> None:
    with pytest.raises(ValueError, match=r"^user must be 1-32 lowercase letters, digits or '-', got "):
        Credential(user, "x" * 16)  # type: ignore[arg-type]


@pytest.mark.parametrize("password", ["x" * 16, "x" * 17, "-_" * 16, "p" * 200])
def test_passwords_of_16_characters_or_more_taken(password: str) -> None:
    assert Credential("agent-2", password).password == password


@pytest.mark.parametrize(
    "password", ["x" * 15, "", ":" + "x" * 16, "x" * 8 + ":" + "x" * 8, "x" * 40 + ":", "x" * 14 + ":", b"x" * 20, None]
)
def test_short_or_colon_passwords_refused(password: object) -> None:
    """``user:password`` lines: a ':' would cut the password short."""
    with pytest.raises(ValueError, match=r"^password must be at least 16 characters without ':'$"):
        Credential("agent-2", password)  # type: ignore[arg-type]


def test_credentials_and_grants_cannot_change_after_their_checks() -> None:
    cred = Credential("agent-2", "x" * 16)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cred.password = "short"  # type: ignore[misc]
    grants = acl.grants("r1", ROBOTS, 1)["agent-2"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        grants.publish = (f"{R}/**",)  # type: ignore[misc]
    assert repr(cred) == "Credential(user='agent-2', password=***)"


def test_new_passwords_are_192_random_bits_each() -> None:
    creds = trust.new_credentials(["world", "agent-1", "agent-2"])
    assert list(creds) == ["world", "agent-1", "agent-2"]
    assert [c.user for c in creds.values()] == list(creds)
    for c in creds.values():
        assert re.fullmatch(r"[A-Za-z0-9_-]{32}", c.password), c.user  # 24 bytes in URL-safe base64
    assert len({c.password for c in creds.values()}) == 3


def test_client_and_router_settings() -> None:
    cred = Credential("agent-2", "p" * 16)
    usrpwd = {"transport/auth/usrpwd": {"user": "agent-2", "password": "p" * 16}}
    assert trust.client_settings(cred) == usrpwd
    assert trust.client_settings(cred, "") == usrpwd
    assert trust.client_settings(cred, "ca.pem") == usrpwd | {"transport/link/tls/root_ca_certificate": "ca.pem"}
    rules = {"enabled": True}
    router = {"transport/auth/usrpwd": {"dictionary_file": "pw.txt"}, "access_control": rules}
    assert trust.router_settings("pw.txt", rules) == router
    assert trust.router_settings("pw.txt", rules, ("r.pem", "r.key")) == router | {
        "transport/link/tls/listen_certificate": "r.pem",
        "transport/link/tls/listen_private_key": "r.key",
    }


# -- the run's secrets on disk --------------------------------------------------------------


@pytest.fixture
def no_umask() -> Iterator[None]:
    old = os.umask(0)
    try:
        yield
    finally:
        os.umask(old)


@pytest.mark.usefixtures("no_umask")
def test_secrets_are_created_private_not_narrowed_afterwards(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The folder is made 0700 and each file 0600 when created: a chmod only
    afterwards would leave a moment in which others could open them."""
    monkeypatch.setattr(os, "chmod", lambda *_a, **_k: None)  # only the modes given at creation remain
    folder = tmp_path / "runs" / "r1" / "secrets"  # its parents are made too
    files = trust.write_run_secrets(folder, "r1", ROBOTS, 1)
    monkeypatch.undo()
    assert _mode(folder) == 0o700
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        ["passwords.txt", "router.json", "logger.json", "launcher.json", "agent-1.json", "agent-2.json", "agent-3.json"]
    )
    assert {p.name: _mode(p) for p in folder.iterdir()} == {p.name: 0o600 for p in folder.iterdir()}
    assert set(files) == {"router", "logger", "launcher", "agent-1", "agent-2", "agent-3"}  # the world is the router
    assert all(path == folder / f"{user}.json" for user, path in files.items())


def test_an_existing_folder_and_file_are_narrowed_and_rewritten(tmp_path: Path) -> None:
    folder = tmp_path / "secrets"
    folder.mkdir()
    os.chmod(folder, 0o755)
    old = folder / "passwords.txt"
    old.write_text("old:" + "x" * 100 + "\n" * 100)
    os.chmod(old, 0o644)
    files = trust.write_run_secrets(folder, "r1", ROBOTS, 1, world="anywhere")
    assert (_mode(folder), _mode(old)) == (0o700, 0o600)
    creds = {u: json.loads(p.read_text())["transport/auth/usrpwd"] for u, p in files.items() if u != "router"}
    assert list(creds) == ["world", "logger", "launcher", "agent-1", "agent-2", "agent-3"]
    assert old.read_text() == "".join(f"{c['user']}:{c['password']}\n" for c in creds.values())  # nothing old left


def test_without_tls_no_tls_setting_is_written(tmp_path: Path) -> None:
    files = trust.write_run_secrets(tmp_path / "s", "r1", ROBOTS, 1)
    client = json.loads(files["agent-2"].read_text())
    assert list(client) == ["transport/auth/usrpwd"]
    assert client["transport/auth/usrpwd"]["user"] == "agent-2"
    assert json.loads(files["router"].read_text()) == {
        "transport/auth/usrpwd": {"dictionary_file": "passwords.txt"},
        "access_control": acl.access_control("r1", ROBOTS, 1),
    }


def test_tls_files_are_copied_private_and_named_relative_to_the_folder(tmp_path: Path) -> None:
    src = tmp_path / "pki"
    src.mkdir()
    for name, text in (("my-ca.pem", "CA"), ("host.pem", "CERT"), ("host.key", "KEY")):
        (src / name).write_text(text)
    tls = trust.Tls(ca=src / "my-ca.pem", certificate=src / "host.pem", private_key=src / "host.key")
    folder = tmp_path / "secrets"
    files = trust.write_run_secrets(folder, "r1", ROBOTS, 1, tls=tls)
    copies = {
        name: ((folder / name).read_text(), _mode(folder / name)) for name in ("ca.pem", "router.pem", "router.key")
    }
    assert copies == {"ca.pem": ("CA", 0o600), "router.pem": ("CERT", 0o600), "router.key": ("KEY", 0o600)}
    client = json.loads(files["agent-2"].read_text())
    password = client["transport/auth/usrpwd"]["password"]
    assert client == {
        "transport/auth/usrpwd": {"user": "agent-2", "password": password},
        "transport/link/tls/root_ca_certificate": "ca.pem",
    }
    assert json.loads(files["router"].read_text()) == {
        "transport/auth/usrpwd": {"dictionary_file": "passwords.txt"},
        "access_control": acl.access_control("r1", ROBOTS, 1),
        "transport/link/tls/listen_certificate": "router.pem",
        "transport/link/tls/listen_private_key": "router.key",
    }
    # Read back, the names are taken from the folder the settings are in.
    assert trust.read_settings(files["agent-2"])["transport/link/tls/root_ca_certificate"] == str(folder / "ca.pem")
    router = trust.read_settings(files["router"])
    assert router["transport/auth/usrpwd"] == {"dictionary_file": str(folder / "passwords.txt")}
    assert router["transport/link/tls/listen_certificate"] == str(folder / "router.pem")
    assert router["transport/link/tls/listen_private_key"] == str(folder / "router.key")


@pytest.mark.parametrize(
    ("world", "hosts", "bound"),
    [
        ("loopback", {"a": Credential("host-a", "p" * 24)}, ["world", "logger"]),  # placed: the logger by the router
        ("loopback", None, ["world"]),
        ("anywhere", {"a": Credential("host-a", "p" * 24)}, []),
        ("router", None, []),
    ],
)
def test_the_logins_bound_to_the_routers_loopback(
    tmp_path: Path, world: str, hosts: dict[str, Credential] | None, bound: list[str]
) -> None:
    files = trust.write_run_secrets(tmp_path / "s", "r1", ROBOTS, 1, world=world, host_logins=hosts)
    subjects = json.loads(files["router"].read_text())["access_control"]["subjects"]
    assert [s["id"] for s in subjects if "interfaces" in s] == bound
    assert all(s["interfaces"] == acl.loopback_interfaces() for s in subjects if "interfaces" in s)


def test_forgetting_a_routers_secrets_leaves_neither_its_passwords_nor_its_tls_key(tmp_path: Path) -> None:
    """What swarm run placed on hosts removes once its router has read them: a
    launcher killed later leaves neither in the run folder."""
    src = tmp_path / "pki"
    src.mkdir()
    for name, text in (("my-ca.pem", "CA"), ("host.pem", "CERT"), ("host.key", "THE ROUTER'S PRIVATE KEY")):
        (src / name).write_text(text)
    tls = trust.Tls(ca=src / "my-ca.pem", certificate=src / "host.pem", private_key=src / "host.key")
    folder = tmp_path / "secrets"
    logins = {"a": Credential("host-a", "p" * 24)}
    files = trust.write_run_secrets(folder, "r1", ROBOTS, 1, world="loopback", tls=tls, host_logins=logins)
    before = {p.name for p in folder.iterdir()}
    assert {"passwords.txt", "router.key"} <= before
    trust.forget_router_secrets(folder)
    assert sorted(before - {p.name for p in folder.iterdir()}) == ["passwords.txt", "router.key"]
    assert not any("p" * 24 in p.read_text() or "PRIVATE KEY" in p.read_text() for p in folder.iterdir())
    assert files["router"].exists()  # the settings the router read stay, naming the files gone
    trust.forget_router_secrets(folder)  # once more: nothing left to remove


# -- reading settings -----------------------------------------------------------------------


def _settings(tmp_path: Path, data: object, mode: int = 0o600) -> Path:
    path = tmp_path / "settings.json"
    path.write_text(json.dumps(data))
    os.chmod(path, mode)
    return path


@pytest.mark.parametrize("bit", [0o040, 0o020, 0o010, 0o004, 0o002, 0o001])
def test_any_right_of_group_or_others_is_refused_with_the_mode(tmp_path: Path, bit: int) -> None:
    p = _settings(tmp_path, {}, 0o600 | bit)
    message = f"{p} is readable by other users (mode {0o600 | bit:o}): chmod 600 {p}"
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        trust.read_settings(p)


def test_the_mode_printed_is_the_permission_bits(tmp_path: Path) -> None:
    p = _settings(tmp_path, {}, 0o644)
    with pytest.raises(ValueError, match=re.escape("(mode 644): chmod 600")):
        trust.read_settings(str(p))


@pytest.mark.parametrize("mode", [0o600, 0o400, 0o700])
def test_owner_only_rights_are_taken(tmp_path: Path, mode: int) -> None:
    assert trust.read_settings(_settings(tmp_path, {"mode": "client"}, mode)) == {"mode": "client"}


def test_a_missing_or_broken_file_says_which(tmp_path: Path) -> None:
    missing = tmp_path / "nope.json"
    with pytest.raises(ValueError, match=f"^cannot read the credentials file {re.escape(str(missing))}: "):
        trust.read_settings(missing)
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    os.chmod(broken, 0o600)
    with pytest.raises(ValueError, match=f"^cannot read the credentials file {re.escape(str(broken))}: "):
        trust.read_settings(broken)
    with pytest.raises(ValueError, match="must hold a JSON object of Zenoh settings"):
        trust.read_settings(_settings(tmp_path, ["mode", "client"]))


def test_only_relative_names_of_file_settings_are_resolved(tmp_path: Path) -> None:
    data = {
        "mode": "client",
        "transport/auth/usrpwd": {"user": "agent-2", "dictionary_file": "pw.txt"},
        "transport/link/tls/root_ca_certificate": "ca.pem",
        "transport/link/tls/listen_certificate": "/etc/pki/router.pem",
        "transport/link/tls/listen_private_key": None,
        "connect": {"endpoints": ["tcp/127.0.0.1:7447"]},
        "root_ca_certificate_note": "ca.pem",
    }
    assert trust.read_settings(_settings(tmp_path, data)) == data | {
        "transport/auth/usrpwd": {"user": "agent-2", "dictionary_file": str(tmp_path / "pw.txt")},
        "transport/link/tls/root_ca_certificate": str(tmp_path / "ca.pem"),
    }
