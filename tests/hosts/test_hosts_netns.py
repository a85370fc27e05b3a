"""One command, three machines: ``swarm run --hosts`` in a network namespace
(launcher, router, world and logger), a ``swarm host`` in each of two others,
joined to the first by a veth pair each, every link with its login and TLS
(a CA made here with openssl; the router's certificate names the address
each host reaches it at).

The run spreads Fig. 11's agents over both hosts, ends in lockstep with the
trajectory digest of a local run with the same seed, and leaves a run folder
``swarm report`` draws. ``swarm doctor``, the hosts' router in its turn (the
same TLS files and logins), hears both with their round trips; with host b's
link down it exits 1 within its --timeout naming b, and hears b again once
the link is back. A second run loses one host mid-run (its ``swarm
host`` is killed): those robots are reported dead, the run exits non-zero
naming the host, and no agent is left on either host.

Needs root, iproute2 (``ip netns``) and openssl; skipped with the reason otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.helpers import Console

PY = [sys.executable, "-m", "formation_swarm.cli"]
PORT = 7447  # in a namespace of its own: free


def _tls_files(folder: Path, ips: list[str]) -> tuple[Path, Path, Path]:
    """A throw-away CA and a router certificate naming ``ips``."""
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make the test's TLS certificates")
    folder.mkdir()
    ca, ca_key, cert, key = (folder / n for n in ("ca.pem", "ca.key", "router.pem", "router.key"))
    ext = folder / "ext.cnf"
    ext.write_text("subjectAltName=" + ",".join(f"IP:{ip}" for ip in ips) + "\n")
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    for argv in (
        ["req", "-x509", *ec, "-keyout", ca_key, "-out", ca, "-days", "1", "-subj", "/CN=swarm test CA"],
        ["req", *ec, "-keyout", key, "-out", folder / "router.csr", "-subj", "/CN=router"],
        [
            "x509",
            "-req",
            "-in",
            folder / "router.csr",
            "-CA",
            ca,
            "-CAkey",
            ca_key,
            "-CAcreateserial",
            "-out",
            cert,
            "-days",
            "1",
            "-extfile",
            ext,
        ],
    ):
        subprocess.run(["openssl", *map(str, argv)], check=True, capture_output=True, timeout=30)
    return ca, cert, key


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=10)


def _pids(ns: str) -> set[int]:
    out = subprocess.run(["ip", "netns", "pids", ns], capture_output=True, text=True, timeout=10, check=False)
    return {int(p) for p in out.stdout.split()}


class Site:
    """Namespaces ``run`` (the launcher's), ``a`` and ``b`` (the hosts'), a
    veth pair from ``run`` to each; the address each host reaches ``run`` at."""

    def __init__(self) -> None:
        tag = uuid.uuid4().hex[:6]
        self.ns = {k: f"swh-{tag}-{k}" for k in ("run", "a", "b")}
        self.router_ip: dict[str, str] = {}
        self.made: list[str] = []
        subnet = 16 + int(tag[:2], 16) % 200
        for i, h in enumerate(("a", "b")):
            self.router_ip[h] = f"10.{78 + i}.{subnet}.1"
        self.tag = tag

    def create(self) -> None:
        for ns in self.ns.values():
            _ip("netns", "add", ns)
            self.made.append(ns)
            _ip("netns", "exec", ns, "ip", "link", "set", "lo", "up")
        for h in ("a", "b"):
            near, far = f"sw{self.tag}{h}r", f"sw{self.tag}{h}h"
            _ip("link", "add", near, "type", "veth", "peer", "name", far)
            _ip("link", "set", near, "netns", self.ns["run"])
            _ip("link", "set", far, "netns", self.ns[h])
            ip = self.router_ip[h]
            _ip("netns", "exec", self.ns["run"], "ip", "addr", "add", f"{ip}/24", "dev", near)
            _ip("netns", "exec", self.ns["run"], "ip", "link", "set", near, "up")
            _ip("netns", "exec", self.ns[h], "ip", "addr", "add", f"{ip[:-1]}2/24", "dev", far)
            _ip("netns", "exec", self.ns[h], "ip", "link", "set", far, "up")

    def delete(self) -> None:
        for ns in self.made:  # deleting a namespace deletes its end of each veth pair, and so the pair
            for pid in _pids(ns):
                with _quiet():
                    os.kill(pid, signal.SIGKILL)
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=10, check=False)

    def exec(self, where: str) -> list[str]:
        return ["ip", "netns", "exec", self.ns[where]]


class _quiet:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> bool:
        return exc[0] is ProcessLookupError


@pytest.fixture
def site() -> Iterator[Site]:
    if os.geteuid() != 0 or shutil.which("ip") is None:
        pytest.skip("needs root and iproute2 to create network namespaces")
    s = Site()
    try:
        try:
            s.create()
        except (subprocess.CalledProcessError, OSError) as exc:
            pytest.skip(f"cannot create network namespaces here: {exc}")
        yield s
    finally:
        s.delete()


def _start_hosts(site: Site, tmp_path: Path) -> dict[str, subprocess.Popen[bytes]]:
    ca, _cert, _key = _tls_files(tmp_path / "tls", list(site.router_ip.values()))
    made = subprocess.run(
        [*PY, "secure", "--hosts", "a,b", "--out", str(tmp_path / "sec"), "--tls-ca", str(ca)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert made.returncode == 0, made.stderr
    procs = {}
    for h in ("a", "b"):
        log = open(tmp_path / f"host-{h}.log", "wb")  # noqa: SIM115 - closed with the process
        auth = tmp_path / "sec" / f"host-{h}.json"
        argv = [
            *site.exec(h),
            *PY,
            "host",
            "--name",
            h,
            "--connect",
            f"tls/{site.router_ip[h]}:{PORT}",
            "--auth",
            str(auth),
            "--workdir",
            str(tmp_path / f"work-{h}"),
        ]
        procs[h] = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        log.close()
    return procs


def _router_flags(site: Site, tmp_path: Path) -> list[str]:
    """Where the router listens for the hosts, their logins and its TLS files: a run's and the doctor's."""
    tls = {
        "ca": tmp_path / "tls" / "ca.pem",
        "cert": tmp_path / "tls" / "router.pem",
        "key": tmp_path / "tls" / "router.key",
    }
    return [
        "--hosts",
        "a,b",
        "--listen",
        f"tls/0.0.0.0:{PORT}",
        "--host-logins",
        str(tmp_path / "sec" / "hosts.txt"),
        *(f for n in ("ca", "cert", "key") for f in (f"--tls-{n}", str(tls[n]))),
    ]


def _run_argv(site: Site, tmp_path: Path, out: Path) -> list[str]:
    return [
        *site.exec("run"),
        *PY,
        "run",
        "fig11_obstacles",
        "--seed",
        "7",
        "--out",
        str(out),
        "--timeout",
        "240",
        *_router_flags(site, tmp_path),
    ]


# The hosts retry their router every 0.5 s at most (protocol.session.make_config), and the
# doctor hears both within a second of its start: 5 s leaves the rest for a busy machine.
DOCTOR_TIMEOUT_S = 5


def _doctor(site: Site, tmp_path: Path) -> tuple[int, list[str], float]:
    """``swarm doctor`` as the hosts' router in the run's namespace: its exit code, its lines, its wall time in s."""
    argv = [*site.exec("run"), *PY, "doctor", "--timeout", str(DOCTOR_TIMEOUT_S), *_router_flags(site, tmp_path)]
    t0 = time.monotonic()
    done = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    took = time.monotonic() - t0
    print(f"doctor: exit {done.returncode} after {took:.1f} s\n{done.stdout}{done.stderr}")
    return done.returncode, done.stdout.splitlines(), took


def _round_trip_ms(lines: list[str], host: str) -> float:
    line = next((x for x in lines if x.startswith(f"  host {host}: heard; round trip ")), None)
    assert line is not None, "\n".join(lines)
    return float(line.split("round trip ")[1].split(" ms;")[0])


def _stop(procs: dict[str, subprocess.Popen[bytes]]) -> None:
    for p in procs.values():
        if p.poll() is None:
            p.terminate()
    for p in procs.values():
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


@pytest.mark.slow
def test_one_command_spreads_fig11_over_two_hosts_and_survives_losing_one(site: Site, tmp_path: Path) -> None:
    # The local run (the digest to match) runs while the hosts start and connect.
    local_argv = [*PY, "run", "fig11_obstacles", "--seed", "7", "--no-logger", "--out", str(tmp_path / "l")]
    local = subprocess.Popen(local_argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    hosts: dict[str, subprocess.Popen[bytes]] = {}
    try:
        hosts = _start_hosts(site, tmp_path)
        local_out, _ = local.communicate(timeout=300)
        assert local.returncode == 0, local_out
        # 1. The run, on both hosts.
        out = tmp_path / "placed"
        run = subprocess.run(_run_argv(site, tmp_path, out), capture_output=True, text=True, timeout=300, check=False)
        assert run.returncode == 0, run.stdout + run.stderr
        summary = json.loads((out / "summary.json").read_text())
        assert (
            summary["trajectory_digest"]
            == json.loads((tmp_path / "l" / "summary.json").read_text())["trajectory_digest"]
        )
        assert summary["placement"] == {"agent-1": "a", "agent-2": "b", "agent-3": "a"}
        assert summary["lockstep_misses"] == 0
        for name in ("world", "logger", "agent-1", "agent-2", "agent-3"):
            assert "exit code 0" in (out / "logs" / f"{name}.log").read_text().splitlines()[-1], name
            assert (out / "stats" / f"{name}.json").is_file(), name
        report = subprocess.run([*PY, "report", str(out)], capture_output=True, text=True, timeout=300, check=False)
        assert report.returncode == 0, report.stdout + report.stderr
        assert (out / "report" / "trajectories.png").stat().st_size > 10_000
        for h in ("a", "b"):  # nothing of the run is left on a host: only the host itself
            assert _pids(site.ns[h]) == {hosts[h].pid} | _children(hosts[h].pid), h

        # The doctor, the hosts' router as the run was: it hears both, then with host b's link down names b.
        code, lines, _ = _doctor(site, tmp_path)
        assert code == 0, "\n".join(lines)
        assert lines[-1].startswith("verdict: OK: ")
        assert "hosts a, b" in lines[-1]
        for h in ("a", "b"):
            assert 0 < _round_trip_ms(lines, h) < 1000, h
        b_end = f"sw{site.tag}bh"
        _ip("netns", "exec", site.ns["b"], "ip", "link", "set", b_end, "down")
        try:
            code, lines, took = _doctor(site, tmp_path)
        finally:
            _ip("netns", "exec", site.ns["b"], "ip", "link", "set", b_end, "up")
        assert code == 1, "\n".join(lines)
        not_heard = (
            "  host b: NOT HEARD: its token did not reach the router (check its --connect, the network and its login)"
        )
        assert not_heard in lines, "\n".join(lines)
        assert lines[-1].startswith("verdict: FAIL: ")
        assert "host b not heard" in lines[-1]
        assert 0 < _round_trip_ms(lines, "a") < 1000
        assert DOCTOR_TIMEOUT_S <= took < DOCTOR_TIMEOUT_S + 10  # the wait, plus starting and closing the session
        deadline = time.monotonic() + 20  # host b back: it reconnects on its own
        while (code := _doctor(site, tmp_path)[0]) != 0 and time.monotonic() < deadline:
            pass
        assert code == 0, "host b did not come back after its link did"

        # 2. The same hosts, a second run; host b dies mid-run.
        out = tmp_path / "lost"
        run = Console(_run_argv(site, tmp_path, out), "[swarm] tick ")
        try:
            assert run.seen.wait(120), run.text
            hosts["b"].kill()
            hosts["b"].wait(timeout=10)
            code = run.wait(240)
        finally:
            run.close()
        text = run.text
        assert code == 1, text
        assert "host b was lost" in text, text
        assert "robots (2) were counted dead" in text, text
        summary = json.loads((out / "summary.json").read_text())
        assert summary["hosts"]["b"]["lost"] is True
        assert [d["robot"] for d in summary["deaths"]] == [2]
        deadline = time.monotonic() + 15
        while _pids(site.ns["b"]) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert _pids(site.ns["b"]) == set()  # host b's agents died with it
        assert _pids(site.ns["a"]) == {hosts["a"].pid} | _children(hosts["a"].pid)
    finally:
        if local.poll() is None:
            local.kill()
            local.wait()
        _stop(hosts)


def _children(pid: int) -> set[int]:
    """The host's own helpers (the spawner's fork server), which outlive a run."""
    out = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            if ppid == pid:
                out.add(int(entry.name))
    return out
