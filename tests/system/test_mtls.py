"""Mutual TLS on loopback: a router with a run's certificate rules lets a
login act only with its own certificate. Another name's certificate (a
robot's, or any other of the same CA) is granted nothing; no certificate, or
one of another CA, is refused at the handshake; a bad file stops a process
at once with one line naming it. tests/hosts/test_mtls_netns.py flies Fig. 11
with these files across network namespaces.

Needs openssl to make the certificates; skipped otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from formation_swarm.launch import certs, secure
from formation_swarm.launch.launcher import free_port
from formation_swarm.protocol import acl, tls, trust
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.session import make_config

ROBOTS = (1, 2, 3)
SENT = 20  # puts of each client that must not arrive


class Site:
    """A run's router with mutual TLS on loopback, the run's logins and
    certificates, and certificates the rules do not know: ``intruder`` (the
    run's CA) and ``agent-2`` of another CA."""

    def __init__(self, tmp_path: Path) -> None:
        if shutil.which("openssl") is None:
            pytest.skip("needs openssl to make the certificates")
        self.run = f"mtls-{uuid.uuid4().hex[:8]}"
        self.keys = Keys(self.run)
        pki = tmp_path / "pki"
        pki.mkdir()
        made = certs.make_run_certificates(pki, list(acl.grants(self.run, ROBOTS, 1)), ["127.0.0.1"])
        self.intruder = certs.make_certificate(pki, "intruder", (made.ca, pki / "ca.key"))
        other = tmp_path / "other"
        other.mkdir()
        self.foreign = certs.make_certificate(other, "agent-2", certs.make_ca(other, "another CA"))
        self.files = trust.write_run_secrets(tmp_path / "s", self.run, ROBOTS, 1, world="anywhere", tls=made)
        self.endpoint = f"tls/127.0.0.1:{free_port()}"
        settings = trust.read_settings(self.files["router"])
        self.session = zenoh.open(make_config("router", listen=[self.endpoint], settings=settings))
        self.sessions = [self.session]

    def client(
        self, user: str, certificate: tuple[Path, Path] | None = None, *, mtls: bool = True, password: bool = True
    ) -> zenoh.Session:
        """A session with ``user``'s login and its own certificate, another
        one, or (``mtls=False``) none; ``password=False``: without the login."""
        settings = trust.read_settings(self.files[user])
        if not password:
            del settings["transport/auth/usrpwd"]
        if certificate is not None:
            settings[tls.CONNECT_CERTIFICATE], settings[tls.CONNECT_PRIVATE_KEY] = map(str, certificate)
        if not mtls:
            for key in (tls.CONNECT_CERTIFICATE, tls.CONNECT_PRIVATE_KEY, tls.ENABLE_MTLS):
                del settings[key]
        s = zenoh.open(make_config("client", [self.endpoint], connect_timeout_s=2.0, settings=settings))
        self.sessions.append(s)
        return s

    def close(self) -> None:
        for s in reversed(self.sessions):
            s.close()


@pytest.fixture
def site(tmp_path: Path) -> Iterator[Site]:
    s = Site(tmp_path)
    try:
        yield s
    finally:
        s.close()


class Count:
    """What a subscriber received (with ``only``, those payloads alone: a
    session also hands its own puts to its subscribers), and an event set at each."""

    def __init__(self, session: zenoh.Session, key: str, only: bytes | None = None) -> None:
        self.got: list[bytes] = []
        self.only = only
        self.event = threading.Event()
        session.declare_subscriber(key, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        if self.only is None or payload == self.only:
            self.got.append(payload)
            self.event.set()

    def wait(self, n: int, timeout_s: float = 10.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while len(self.got) < n and time.monotonic() < deadline:
            self.event.wait(0.05)
            self.event.clear()
        return len(self.got) >= n


def test_a_login_with_its_own_certificate_does_what_its_role_does(site: Site) -> None:
    k = site.keys
    at_router = Count(site.session, k.all_cmd)
    agent2 = site.client("agent-2")
    inbox = Count(agent2, k.inbox(2), only=b"obs")
    agent2.declare_publisher(k.cmd(2)).put(b"agent-2")
    assert at_router.wait(1)
    deadline = time.monotonic() + 10
    while not inbox.got and time.monotonic() < deadline:  # until the router knows the subscriber
        site.session.put(k.obs(2), b"obs")
        inbox.wait(1, timeout_s=0.2)
    assert at_router.got == [b"agent-2"]
    assert inbox.got[:1] == [b"obs"]


@pytest.mark.parametrize("name", ["agent-3", "intruder"])
def test_a_certificate_of_another_name_is_granted_nothing(site: Site, name: str) -> None:
    """agent-2's password with agent-3's certificate, or with one of the run's
    CA named ``intruder``: the session opens (the handshake checks the CA, the
    rules the name) and no put of it arrives, nothing reaches its subscriber."""
    k = site.keys
    at_router = Count(site.session, k.all_cmd)
    folder = site.files["agent-3"].parent
    pair = site.intruder if name == "intruder" else (folder / "agent-3.pem", folder / "agent-3.key")
    wrong = site.client("agent-2", pair)
    heard = Count(wrong, k.inbox(2), only=b"obs")
    right = site.client("agent-2")
    inbox = Count(right, k.inbox(2), only=b"obs")
    publisher = wrong.declare_publisher(k.cmd(2))
    for _ in range(SENT):
        publisher.put(b"wrong")
    deadline = time.monotonic() + 10
    while not inbox.got and time.monotonic() < deadline:  # the router's puts reach the right one
        site.session.put(k.obs(2), b"obs")
        inbox.wait(1, timeout_s=0.2)
    site.sessions.remove(wrong)
    wrong.close()  # its queue flushed: every put it made has reached the router
    right.declare_publisher(k.cmd(2)).put(b"right")
    assert at_router.wait(1)
    assert inbox.got, "the right certificate heard nothing"
    assert heard.got == []
    assert at_router.got == [b"right"]


def test_no_certificate_one_of_another_ca_or_no_password_is_refused(site: Site) -> None:
    for kwargs in ({"mtls": False}, {"certificate": site.foreign}, {"password": False}):
        t0 = time.monotonic()
        with pytest.raises(zenoh.ZError, match="Unable to connect"):
            site.client("agent-2", **kwargs)
        assert time.monotonic() - t0 < 10


def test_swarm_secure_mtls_leaves_no_ca_key(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make the certificates")
    work = tmp_path / "tmp"
    work.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(work))
    out = tmp_path / "sec"
    argv = ["fig11_obstacles", "--run", "r1", "--out", str(out), "--mtls", "--router-address", "10.1.2.3"]
    assert secure.main(argv) == 0
    assert list(work.iterdir()) == []  # the CA's key went with the folder it was made in
    users = ["world", "logger", "launcher", "agent-1", "agent-2", "agent-3"]
    expected = {"ca.pem", "router.pem", "router.key", "router.json", "passwords.txt"}
    expected |= {f"{u}{ext}" for u in users for ext in (".json", ".pem", ".key")}
    assert {p.name for p in out.iterdir()} == expected
    assert {oct(p.stat().st_mode & 0o777) for p in out.iterdir()} == {"0o600"}
    names = subprocess.run(
        ["openssl", "x509", "-in", str(out / "agent-2.pem"), "-noout", "-subject"],
        capture_output=True,
        text=True,
        check=True,
        timeout=30,
    )
    assert names.stdout.strip().replace(" ", "") == "subject=CN=agent-2"
    router = json.loads((out / "router.json").read_text())
    assert router["access_control"] == acl.access_control("r1", ROBOTS, 1, mtls=True, local=("world",))
    assert tls.certificate_names(out / "router.pem") == {"10.1.2.3", "127.0.0.1"}  # the world's, on its machine


def _start(argv: list[str]) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "formation_swarm.cli", *argv]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)


def test_a_bad_certificate_file_stops_a_process_with_one_line_naming_it(site: Site, tmp_path: Path) -> None:
    login = trust.read_settings(site.files["agent-2"])
    foreign_key = str(site.files["agent-3"].parent / "agent-3.key")
    login[tls.CONNECT_PRIVATE_KEY] = foreign_key
    bad = trust.write_settings(tmp_path / "agent-2-bad.json", login)
    common = ["--scenario", "fig11_obstacles", "--run", site.run, "--connect", site.endpoint, "--peers-timeout", "60"]
    t0 = time.monotonic()
    agent = _start(["agent", "--id", "2", *common, "--auth", str(bad)])
    assert agent.returncode == 2, agent.stderr
    cert = login[tls.CONNECT_CERTIFICATE]
    said = f"TLS file {foreign_key} (connect_private_key): not the private key of the certificate {cert}"
    assert [line for line in agent.stderr.splitlines() if line.strip()] == [f"agent 2: {said}"]
    assert time.monotonic() - t0 < 60  # at once, not after --peers-timeout
    router = trust.read_settings(site.files["router"])
    gone = str(tmp_path / "router-gone.pem")
    router[tls.LISTEN_CERTIFICATE] = gone
    bad_router = trust.write_settings(tmp_path / "router-bad.json", router)
    listen = f"tls/127.0.0.1:{free_port()}"
    refused = _start(["router", "--listen", listen, "--auth", str(bad_router)])
    assert refused.returncode == 2, refused.stderr
    assert refused.stderr.strip() == f"router: TLS file {gone} (listen_certificate): No such file or directory"
    assert os.path.exists(site.files["router"])  # a refused start deletes nothing
