"""The router's walls: who may connect, publish and subscribe on a run's keys."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from formation_swarm.launch.launcher import free_port
from formation_swarm.protocol import trust
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.session import make_config

ROBOTS = (1, 2, 3)


class Router:
    """A run's router (as the world of a local run is), with its access rules."""

    def __init__(self, tmp_path: Path) -> None:
        self.run = f"trust-{uuid.uuid4().hex[:8]}"
        self.keys = Keys(self.run)
        self.files = trust.write_run_secrets(tmp_path / "secrets", self.run, ROBOTS, leader_id=1)
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        conf = make_config("router", listen=[self.endpoint], settings=trust.read_settings(self.files["router"]))
        self.session = zenoh.open(conf)
        self.sessions: list[zenoh.Session] = [self.session]

    def client(self, user: str | None, password: str | None = None) -> zenoh.Session:
        settings = trust.read_settings(self.files[user]) if user and password is None else {}
        if password is not None:
            settings = trust.client_settings(trust.Credential(user or "nobody", password))
        conf = make_config("client", [self.endpoint], connect_timeout_s=2.0, settings=settings)
        s = zenoh.open(conf)
        self.sessions.append(s)
        return s

    def close(self) -> None:
        for s in reversed(self.sessions):
            s.close()


@pytest.fixture
def router(tmp_path: Path) -> Iterator[Router]:
    r = Router(tmp_path)
    try:
        yield r
    finally:
        r.close()


def collect(session: zenoh.Session, key: str) -> tuple[list[str], threading.Event]:
    got: list[str] = []
    event = threading.Event()

    def on(sample: zenoh.Sample) -> None:
        got.append(str(sample.key_expr))
        event.set()

    session.declare_subscriber(key, on)
    return got, event


def wait_for(cond: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


def test_secrets_are_private_and_fresh(tmp_path: Path) -> None:
    a = trust.write_run_secrets(tmp_path / "a", "r1", ROBOTS, 1)
    b = trust.write_run_secrets(tmp_path / "b", "r1", ROBOTS, 1)
    assert set(a) == {"logger", "launcher", "agent-1", "agent-2", "agent-3", "router"}  # the world is the router
    assert "world" in trust.write_run_secrets(tmp_path / "c", "r1", ROBOTS, 1, world="anywhere")
    assert stat.S_IMODE(os.stat(tmp_path / "a").st_mode) == 0o700
    for path in [*a.values(), tmp_path / "a" / "passwords.txt"]:
        assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    assert json.loads(a["agent-2"].read_text()) != json.loads(b["agent-2"].read_text())
    assert "password=***" in repr(trust.Credential("agent-2", "x" * 20))
    os.chmod(a["logger"], 0o644)
    with pytest.raises(ValueError, match="readable by other users"):
        trust.read_settings(a["logger"])


def test_no_credentials_or_a_wrong_password_cannot_connect(router: Router) -> None:
    with pytest.raises(zenoh.ZError):
        router.client(None)
    with pytest.raises(zenoh.ZError):
        router.client("agent-2", password="not-the-password-of-agent-2")


def test_each_role_publishes_only_its_own_keys(router: Router) -> None:
    k = router.keys
    cmds, _ = collect(router.session, k.all_cmd)
    codes, _ = collect(router.session, k.codes)
    agent2 = router.client("agent-2")
    leader = router.client("agent-1")
    # The refused puts go first; the allowed ones after them on the same link
    # (in order), so once these arrived the others would have.
    agent2.put(k.status, b"done")  # only the world may end a run
    one_robot = f"{k.prefix}/robot/3/formation"
    for s, key in [(agent2, k.cmd(3)), (agent2, k.codes), (agent2, one_robot), (leader, k.codes), (agent2, k.cmd(2))]:
        s.declare_publisher(key).put(b"x")
    assert wait_for(lambda: cmds == [k.cmd(2)] and codes == [k.codes])
    assert cmds == [k.cmd(2)]
    assert codes == [k.codes]


def test_the_leaders_one_put_of_a_code_reaches_every_follower_and_no_one_else(router: Router) -> None:
    k = router.keys
    inbox2, _ = collect(router.client("agent-2"), k.inbox(2))
    inbox3, _ = collect(router.client("agent-3"), k.inbox(3))
    by_logger, _ = collect(router.client("logger"), k.codes)  # the logger reads them: the leader's switches
    pub = router.client("agent-1").declare_publisher(k.codes)
    deadline = time.monotonic() + 5.0
    while not (inbox2 and inbox3) and time.monotonic() < deadline:  # until the router knows both inboxes
        pub.put(b"x")
        time.sleep(0.02)
    assert inbox2, inbox3
    assert inbox3, inbox2
    assert set(inbox2) == set(inbox3) == {k.codes}
    assert wait_for(lambda: by_logger)
    assert set(by_logger) == {k.codes}


def test_each_role_hears_only_what_it_needs(router: Router) -> None:
    k = router.keys
    agent2, logger = router.client("agent-2"), router.client("logger")
    heard2, _ = collect(agent2, f"{k.prefix}/**")  # refused at the router: it only hears what its inbox gets
    inbox2, _ = collect(agent2, k.inbox(2))
    truth, _ = collect(logger, k.truth)
    obs3_by_logger, _ = collect(logger, k.obs(3))  # refused: the logger does not read observations
    pubs = {key: router.session.declare_publisher(key) for key in (k.obs(3), k.truth, k.obs(2))}
    assert wait_for(lambda: pubs[k.obs(2)].matching_status.matching and pubs[k.truth].matching_status.matching)
    assert not pubs[k.obs(3)].matching_status.matching  # nobody may read robot 3's observations
    for pub in pubs.values():  # in this order on each link
        pub.put(b"x")
    assert wait_for(lambda: inbox2 == [k.obs(2)] and truth == [k.truth] and heard2 == [k.obs(2)])
    assert obs3_by_logger == []


def test_a_role_cannot_hold_another_robots_liveliness_token(router: Router) -> None:
    k = router.keys
    seen: list[str] = []
    router.session.liveliness().declare_subscriber(f"{k.prefix}/alive/*/*", lambda s: seen.append(str(s.key_expr)))
    agent2 = router.client("agent-2")
    agent2.liveliness().declare_token(k.alive("agent", 3))
    agent2.liveliness().declare_token(k.alive("agent", 2))
    assert wait_for(lambda: k.alive("agent", 2) in seen)  # declared after the refused one, on the same link
    assert set(seen) == {k.alive("agent", 2)}


@pytest.mark.parametrize(
    ("role", "login", "said"),
    [
        (
            ["agent", "--id", "2"],
            "agent-3",
            "agent 2: --auth {f}: this login is for agent-3, not for agent-2: give"
            " agent-2.json of the run's swarm secure",
        ),
        (
            ["logger", "--out", "{tmp}/r.rrd"],
            "agent-3",
            "logger: --auth {f}: this login is for agent-3, not for logger",
        ),
        (["world"], "logger", "world: --auth {f}: this login is for logger, not for world"),
    ],
)
def test_a_role_given_another_roles_login_is_refused_before_it_connects(
    tmp_path: Path, role: list[str], login: str, said: str
) -> None:
    """The router would let it in, and its rules keep it from every key it needs:
    an agent 2 with agent 3's login waited out the run and then said it ended well."""
    files = trust.write_run_secrets(tmp_path / "secrets", "r1", ROBOTS, leader_id=1, world="anywhere")
    argv = [
        sys.executable,
        "-m",
        "formation_swarm.cli",
        *[a.format(tmp=tmp_path) for a in role],
        "--scenario",
        "fig11_obstacles",
        "--run",
        "r1",
        "--connect",
        "tcp/127.0.0.1:9",
        "--auth",
        str(files[login]),
        "--peers-timeout",
        "120",
    ]
    t0 = time.monotonic()
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=180, check=False)
    assert proc.returncode == 2, proc.stderr
    assert said.format(f=files[login]) in proc.stderr
    assert time.monotonic() - t0 < 60  # at once (a few s; loaded, 20): not after the 120 s of --peers-timeout


def test_the_hosts_logins_file_refuses_a_login_file_and_names_a_bad_line(tmp_path: Path) -> None:
    files = trust.write_host_logins(tmp_path / "hosts", ["b", "c"])
    assert set(trust.read_host_logins(files[trust.HOST_LOGINS], ["b", "c"])) == {"b", "c"}
    with pytest.raises(ValueError, match="is a JSON file \\(a process's login\\?\\), not the hosts' list"):
        trust.read_host_logins(files["host-b"], ["b"])  # the host's own file, given by mistake
    bad = tmp_path / "bad.txt"
    bad.write_text(files[trust.HOST_LOGINS].read_text() + "host-d:short\n")
    bad.chmod(0o600)
    with pytest.raises(ValueError, match=f"{bad}, line 3: password must be at least 16 characters"):
        trust.read_host_logins(bad, ["b"])
