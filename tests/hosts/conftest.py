"""Fixtures of the tests that spread a run over hosts: on loopback, and over network namespaces."""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.hosts.local_hosts import Hosts, make_tls


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=10)


def _own_subnet(host_if: str) -> tuple[str, str]:
    """(router-side, robot-side) addresses of a 10.77.N.0/24 no other test
    holds, the router's given to ``host_if``: under a lock, as tests run in
    parallel (pytest-xdist) may each make a namespace."""
    with open(Path(tempfile.gettempdir()) / "formation-swarm-netns.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        taken = subprocess.run(["ip", "-o", "-4", "addr"], capture_output=True, text=True, timeout=10).stdout
        subnet = next(n for n in range(16, 250) if f" 10.77.{n}." not in taken)
        _ip("addr", "add", f"10.77.{subnet}.1/24", "dev", host_if)
    return f"10.77.{subnet}.1", f"10.77.{subnet}.2"


@pytest.fixture
def robot_host() -> object:
    """(namespace, router-side address, robot-side address), torn down after."""
    if os.geteuid() != 0 or shutil.which("ip") is None:
        pytest.skip("needs root and iproute2 to create a network namespace")
    tag = uuid.uuid4().hex[:6]
    ns, host_if, ns_if = f"swarm-{tag}", f"sw{tag}h", f"sw{tag}n"
    try:
        _ip("netns", "add", ns)
    except (subprocess.CalledProcessError, OSError) as exc:
        pytest.skip(f"cannot create a network namespace here: {exc}")
    try:
        _ip("link", "add", host_if, "type", "veth", "peer", "name", ns_if)
        _ip("link", "set", ns_if, "netns", ns)
        host_ip, ns_ip = _own_subnet(host_if)
        _ip("link", "set", host_if, "up")
        _ip("netns", "exec", ns, "ip", "addr", "add", f"{ns_ip}/24", "dev", ns_if)
        _ip("netns", "exec", ns, "ip", "link", "set", ns_if, "up")
        _ip("netns", "exec", ns, "ip", "link", "set", "lo", "up")
        yield ns, host_ip, ns_ip
    finally:
        subprocess.run(["ip", "link", "del", host_if], capture_output=True, timeout=10)
        subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=10)


@pytest.fixture
def two_hosts(tmp_path: Path) -> Iterator[Hosts]:
    hosts = Hosts(tmp_path, ["a", "b"])
    try:
        yield hosts
    finally:
        hosts.close()


@pytest.fixture
def two_tls_hosts(tmp_path: Path) -> Iterator[Hosts]:
    """``two_hosts``, their router's link over TLS."""
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make the test's TLS certificates")
    hosts = Hosts(tmp_path, ["a", "b"], tls=make_tls(tmp_path / "tls"))
    try:
        yield hosts
    finally:
        hosts.close()
