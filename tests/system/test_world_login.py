"""The world's login of ``swarm secure`` is granted over the router's loopback
only: on the router's machine it hears the robots' commands; over the
machine's outward interface the same password is granted nothing, unless
the logins were made with --world-anywhere. A world started elsewhere says
why it heard no one; a given TLS certificate that names no loopback address
is refused before anything is written.

Needs an interface other than loopback; skipped otherwise.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from formation_swarm.launch.launcher import free_port
from formation_swarm.protocol import trust
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.session import make_config
from tests.helpers import outward_address

PY = [sys.executable, "-m", "formation_swarm.cli"]
HEARD_S = 30.0  # the bound on putting commands; quiet, 40 reach the loopback world within about 1 s


def _secure(out: Path, run: str, *extra: str) -> subprocess.CompletedProcess[str]:
    argv = [*PY, "secure", "fig11_obstacles", "--run", run, "--out", str(out), *extra]
    return subprocess.run(argv, capture_output=True, text=True, timeout=120, check=False)


class Router:
    """A run's router from ``swarm secure``'s files, on every interface."""

    def __init__(self, secure: Path, run: str) -> None:
        self.secure, self.keys, self.port = secure, Keys(run), free_port()
        settings = trust.read_settings(secure / "router.json")
        self.sessions = [zenoh.open(make_config("router", listen=[f"tcp/0.0.0.0:{self.port}"], settings=settings))]

    def client(self, user: str, address: str) -> zenoh.Session:
        settings = trust.read_settings(self.secure / f"{user}.json")
        conf = make_config("client", [f"tcp/{address}:{self.port}"], connect_timeout_s=10.0, settings=settings)
        self.sessions.append(zenoh.open(conf))
        return self.sessions[-1]

    def close(self) -> None:
        for s in reversed(self.sessions):
            s.close()


@pytest.fixture
def outward() -> str:
    address = outward_address()
    if address is None:
        pytest.skip("no network interface but loopback: nothing to reach the router from")
    return address


@pytest.fixture
def run() -> str:
    return f"wl-{uuid.uuid4().hex[:8]}"


@pytest.fixture
def router_of() -> Iterator[dict[str, Router]]:
    made: dict[str, Router] = {}
    yield made
    for r in made.values():
        r.close()


def _heard(r: Router, outward: str, *, both: bool) -> dict[str, int]:
    """Commands of agent 1 heard by the world's login over loopback and over
    ``outward``, put every 20 ms until the loopback one has heard 40 (and
    with ``both`` the outward one 20 too), or HEARD_S passes. The outward
    subscriber is declared first: had it been granted, it would have heard
    most of what reached the loopback one."""
    heard = {"loopback": 0, "outward": 0}
    lock = threading.Lock()

    def count(where: str) -> object:
        def on(_sample: zenoh.Sample) -> None:
            with lock:
                heard[where] += 1

        return on

    for where, address in (("loopback", "127.0.0.1"), ("outward", outward)):
        r.client("world", address).declare_subscriber(r.keys.all_cmd, count(where))
    publisher = r.client("agent-1", "127.0.0.1").declare_publisher(r.keys.cmd(1))
    deadline = time.monotonic() + HEARD_S

    def enough() -> bool:
        with lock:
            return heard["loopback"] >= 40 and (heard["outward"] >= 20 or not both)

    while not enough() and time.monotonic() < deadline:
        publisher.put(b"a command")
        time.sleep(0.02)
    with lock:
        return dict(heard)


def test_the_worlds_login_is_granted_on_the_routers_loopback_only(
    tmp_path: Path, run: str, outward: str, router_of: dict[str, Router]
) -> None:
    made = _secure(tmp_path / "sec", run)
    assert made.returncode == 0, made.stderr
    assert "--connect tcp/127.0.0.1:7447 --auth" in made.stdout
    assert "(on the router's machine: granted there only)" in made.stdout
    router_of["r"] = Router(tmp_path / "sec", run)
    heard = _heard(router_of["r"], outward, both=False)
    assert heard["loopback"] >= 40
    assert heard["outward"] == 0


def test_world_anywhere_grants_the_worlds_login_on_any_link(
    tmp_path: Path, run: str, outward: str, router_of: dict[str, Router]
) -> None:
    made = _secure(tmp_path / "sec", run, "--world-anywhere")
    assert made.returncode == 0, made.stderr
    assert "--connect tcp/ROUTER:7447 --auth" in made.stdout
    router_of["r"] = Router(tmp_path / "sec", run)
    heard = _heard(router_of["r"], outward, both=True)
    assert heard["loopback"] >= 40
    assert heard["outward"] >= 20


def test_a_world_elsewhere_says_its_login_is_for_the_routers_machine(
    tmp_path: Path, run: str, outward: str, router_of: dict[str, Router]
) -> None:
    assert _secure(tmp_path / "sec", run).returncode == 0
    router_of["r"] = r = Router(tmp_path / "sec", run)
    argv = [*PY, "world", "--scenario", "fig11_obstacles", "--run", run, "--zenoh-mode", "client"]
    argv += ["--connect", f"tcp/{outward}:{r.port}", "--auth", str(tmp_path / "sec" / "world.json")]
    done = subprocess.run([*argv, "--peers-timeout", "2"], capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 3, done.stdout + done.stderr
    said = done.stderr.strip().splitlines()
    assert said[-2].startswith("world: gave up after 2 s: no agent for robots 1, 2, 3")
    assert said[-1] == (
        "world: it heard no process of the run at all: a world's login from swarm secure is granted over the "
        "router's loopback only, so connect it to 127.0.0.1 on the router's machine (or make the logins with "
        "--world-anywhere)"
    )


def _certificate(folder: Path, names: str) -> tuple[Path, Path, Path]:
    """A CA and a router certificate (and key) with these subjectAltName entries."""
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make the certificates")
    from formation_swarm.launch import certs

    folder.mkdir()
    ca = certs.make_ca(folder)
    cert, key = certs.make_certificate(folder, "router", ca, names.split(","))
    return ca[0], cert, key


def test_a_given_certificate_must_name_a_loopback_address(tmp_path: Path, run: str) -> None:
    ca, cert, key = _certificate(tmp_path / "pki", "10.1.2.3")
    tls = ["--tls-ca", str(ca), "--tls-cert", str(cert), "--tls-key", str(key)]
    refused = _secure(tmp_path / "sec", run, *tls)
    assert refused.returncode == 2
    assert f"argument --tls-cert: {cert} names 10.1.2.3, not 127.0.0.1 or localhost" in refused.stderr
    assert not (tmp_path / "sec").exists()
    assert _secure(tmp_path / "anywhere", run, *tls, "--world-anywhere").returncode == 0
    ca, cert, key = _certificate(tmp_path / "pki2", "10.1.2.3,localhost")
    named = _secure(tmp_path / "named", run, "--tls-ca", str(ca), "--tls-cert", str(cert), "--tls-key", str(key))
    assert named.returncode == 0, named.stderr
    assert "--connect tls/localhost:7447 --auth" in named.stdout
