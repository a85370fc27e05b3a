"""``swarm host`` set up: what a host refuses, where robots are placed, auth
paths and TLS files, a host losing its router, the sentences that name a
lost host, and the logins a killed host left."""

from __future__ import annotations

import contextlib
import json
import os
import queue
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import msgpack
import pytest
import zenoh

from formation_swarm import __version__
from formation_swarm.launch.launcher import free_port
from formation_swarm.protocol import trust
from formation_swarm.protocol.hostmsg import HostReply, HostRequest
from formation_swarm.protocol.keys import HostKeys
from formation_swarm.protocol.session import make_config
from tests.helpers import processes

PY = [sys.executable, "-m", "formation_swarm.cli"]


def _start(**fields: Any) -> HostRequest:
    """A request of this version to start agent-2 of run r1, under its own login; ``fields`` override these."""
    defaults: dict[str, Any] = {
        "run": "r1",
        "process": "agent-2",
        "scenario": "x = 1",
        "user": "agent-2",
        "password": "p" * 24,
    }
    return HostRequest("start", __version__, **(defaults | fields))


def test_a_host_refuses_another_version_bad_requests_and_robots_it_may_not_run(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    log = open(tmp_path / "host.log", "wb")  # noqa: SIM115 - closed with the process
    host = subprocess.Popen(
        [*PY, "host", "--connect", endpoint, "--name", "a", "--robots", "2,3", "--workdir", str(tmp_path / "work")],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    log.close()
    router = zenoh.open(make_config("router", listen=[endpoint]))
    try:

        def ask(payload: bytes) -> HostReply:
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:
                got = [r.ok for r in router.get(HostKeys("a").ctl, payload=payload, timeout=2.0) if r.ok is not None]
                if got:
                    return HostReply.from_bytes(got[0].payload.to_bytes())
            raise AssertionError("host a never answered")

        info = ask(HostRequest("info", __version__).to_bytes())
        assert info.ok
        said = (tmp_path / "host.log").read_text()
        assert f"host a: connected to a router at {endpoint}; serving robots 2, 3" in said
        assert info.robots == (2, 3)
        assert info.cores == os.cpu_count()
        other = ask(HostRequest("info", "0.0.1").to_bytes())
        assert not other.ok
        assert other.error == (
            f"host a runs formation_swarm {__version__}, the launcher 0.0.1: install the same "
            "version on every machine of a run"
        )
        bad = ask(msgpack.packb({"op": "start"}))
        assert not bad.ok
        assert bad.error.startswith("bad request: missing field")
        start = _start(process="agent-1", user="agent-1")
        refused = ask(start.to_bytes()).error
        assert refused.startswith("host a may run robots ")
        assert re.findall(r"\d+", refused) == ["2", "3", "1"]  # its robots, then the one asked for
        wrong_login = _start(user="agent-3")
        assert "must be agent-2" in ask(wrong_login.to_bytes()).error
        assert "started" not in (tmp_path / "host.log").read_text()
    finally:
        router.close()
        host.terminate()
        assert host.wait(timeout=20) == 0


def test_a_scenario_s_placement_is_checked_and_place_wins_over_it(tmp_path: Path) -> None:
    from formation_swarm.launch.launcher import Launch
    from formation_swarm.spec.scenario import ScenarioError, load

    sc = load("fig11_obstacles", {"placement": {"1": "b", "3": "c"}})
    assert sc.placement == ((1, "b"), (3, "c"))
    with pytest.raises(ScenarioError, match="'9' is not a robot of this run"):
        load("fig11_obstacles", {"placement": {"9": "b"}})
    with pytest.raises(ScenarioError, match="placement.1: host name must be"):
        load("fig11_obstacles", {"placement": {"1": "B C"}})
    logins = trust.write_host_logins(tmp_path / "sec", ["b", "c"])[trust.HOST_LOGINS]
    common = {"listen": "tcp/127.0.0.1:7447", "host_logins": logins, "out": tmp_path / "run"}
    launch = Launch(
        "fig11_obstacles", overrides={"placement": {"1": "b", "3": "c"}}, hosts=["b", "c"], placement={3: "b"}, **common
    )
    assert launch.explicit == {1: "b", 3: "b"}
    alone = Launch("fig11_obstacles", overrides={"placement": {"1": "b"}}, out=tmp_path / "alone")
    assert alone.explicit == {}  # a run on this machine alone ignores it
    with pytest.raises(ValueError, match="c is not one of --hosts b"):
        Launch("fig11_obstacles", overrides={"placement": {"1": "c"}}, hosts=["b"], **common)


def test_a_relative_auth_path_gives_the_agents_absolute_existing_files(tmp_path: Path) -> None:
    """``swarm host --auth host-a.json`` run from the folder of that file: the CA
    it names (relative to it) reaches the agents' logins as an absolute path."""
    ca = tmp_path / "made-ca.pem"
    ca.write_text("-----BEGIN CERTIFICATE-----\n-----END CERTIFICATE-----\n")  # only read on a tls/ link
    sec = tmp_path / "sec"
    trust.write_host_logins(sec, ["a"], tls_ca=ca)
    settings = json.loads((sec / "host-a.json").read_text())
    assert settings["transport/link/tls/root_ca_certificate"] == trust.CA  # relative to the file, as written
    run = f"rel-{uuid.uuid4().hex[:8]}"
    files = trust.write_run_secrets(
        tmp_path / "run",
        run,
        (1, 2),
        1,
        world="loopback",
        host_logins=trust.read_host_logins(sec / trust.HOST_LOGINS, ["a"]),
    )
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(make_config("router", listen=[endpoint], settings=trust.read_settings(files["router"])))
    log = open(tmp_path / "host.log", "wb")  # noqa: SIM115 - closed with the process
    host = subprocess.Popen(
        [
            *PY,
            "host",
            "--connect",
            endpoint,
            "--name",
            "a",
            "--auth",
            "host-a.json",
            "--workdir",
            str(tmp_path / "work"),
        ],
        cwd=sec,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    log.close()
    launcher = zenoh.open(make_config("client", [endpoint], settings=trust.read_settings(files["launcher"])))
    try:
        agent = trust.read_settings(files["agent-2"])["transport/auth/usrpwd"]
        start = _start(run=run, password=agent["password"])
        reply = None
        deadline = time.monotonic() + 60
        while reply is None and time.monotonic() < deadline:
            got = [r.ok for r in launcher.get(HostKeys("a").ctl, payload=start.to_bytes(), timeout=2.0) if r.ok]
            reply = HostReply.from_bytes(got[0].payload.to_bytes()) if got else None
        assert reply is not None, (tmp_path / "host.log").read_text()
        assert reply.ok, reply.error
        written = json.loads((tmp_path / "work" / run / "secrets" / "agent-2.json").read_text())
        named = Path(written["transport/link/tls/root_ca_certificate"])
        assert named.is_absolute()
        assert named == sec / trust.CA
        assert named.read_text() == ca.read_text()
        assert written["transport/auth/usrpwd"]["user"] == "agent-2"
    finally:
        launcher.close()
        host.terminate()
        assert host.wait(timeout=20) == 0
        router.close()
    # Its fork server (whose path names the folder it ran in) leaves once the host has gone.
    deadline = time.monotonic() + 10
    while processes(lambda cmd: str(sec) in cmd) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not processes(lambda cmd: str(sec) in cmd)


def test_a_host_waiting_for_its_router_says_so_and_stops_at_once_on_sigterm(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"  # nothing listens there
    host = subprocess.Popen(
        [*PY, "host", "--connect", endpoint, "--name", "b", "--workdir", str(tmp_path / "work")],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert host.stdout is not None
        first = host.stdout.readline()  # said before it waits
        assert first.startswith(f"host b: waiting for a router at {endpoint} (retrying)"), first
        time.sleep(1.0)  # well into its retries: the case that hung
        host.send_signal(signal.SIGTERM)
        sent = time.monotonic()
        code = host.wait(timeout=20)
        took = time.monotonic() - sent
    finally:
        if host.poll() is None:
            host.kill()
            host.wait()
    assert code in (0, 143)
    assert took < 10.0, took  # at once (under 1 s quiet): the case that hung never stopped
    assert "stopped before a router answered" in host.stdout.read()


def test_a_host_says_when_its_router_goes_and_comes_back(tmp_path: Path) -> None:
    """Its log (a service's journal) said "connected" to the end: an operator read it as connected."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    lines: queue.SimpleQueue[str] = queue.SimpleQueue()
    router = zenoh.open(make_config("router", listen=[endpoint]))
    host = subprocess.Popen(
        [*PY, "host", "--connect", endpoint, "--name", "b", "--workdir", str(tmp_path / "work")],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    threading.Thread(target=lambda: [lines.put(line) for line in host.stdout], daemon=True).start()  # type: ignore[union-attr]

    def said(fragment: str, timeout_s: float = 30.0) -> str:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):
                line = lines.get(timeout=0.1)
                if fragment in line:
                    return line
        raise AssertionError(f"the host never said {fragment!r}")

    try:
        said("connected to a router at")
        router.close()
        assert said("lost its router at").strip() == (
            f"host b: lost its router at {endpoint}; retrying (runs cannot reach this host meanwhile; "
            "the router of swarm run --hosts, its launcher, goes when its run ends)"
        )
        router = zenoh.open(make_config("router", listen=[endpoint]))
        again = said("connected again")
        assert again.startswith("host b: connected again ")
        assert again.strip().endswith(f" at {endpoint}")
    finally:
        host.terminate()
        host.wait(timeout=20)
        router.close()


def test_a_lost_host_and_its_agents_are_told_in_sentences_and_name_the_failure() -> None:
    from formation_swarm.launch.console import describe_event
    from formation_swarm.runtime import summary as summary_mod
    from formation_swarm.spec.scenario import load

    lost = {"event": "host lost", "host": "c", "robots": [2], "sim_time_s": 5.300000000000001, "wall_s": 8.33}
    assert describe_event(lost) == "host c lost at sim t=5.30 s: robot 2 counted dead"
    assert describe_event({**lost, "robots": [2, 3]}).endswith(": robots 2, 3 counted dead")
    agent = {"event": "exited", "process": "agent-2", "sim_time_s": 5.3, "host_lost": "c"}
    with_host = describe_event(agent)
    assert with_host.startswith("agent-2 lost with host c ")  # not an exit code: it stayed on that host
    assert with_host.endswith(" at sim t=5.30 s")
    events = [lost, agent]
    summary = summary_mod.build(
        run_id="r1",
        sc=load("fig11_obstacles"),
        mode="lockstep",
        parts={},
        exit_code=1,
        end_reason=summary_mod.ROLE_FAILED,
        ended_at_s=5.3,
        interrupted=False,
        timed_out=False,
        processes={},
        events=events,
        recording=None,
    )
    assert summary["failure"] == describe_event(lost)
    assert "255" not in summary["ended"]


def test_secure_hosts_with_a_ca_suggests_tls_endpoints_and_says_to_copy_the_ca(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from formation_swarm.launch import secure

    ca = tmp_path / "my-ca.pem"
    ca.write_text("-----BEGIN CERTIFICATE-----\n-----END CERTIFICATE-----\n")
    assert secure.main(["--hosts", "b,c", "--out", str(tmp_path / "tls"), "--tls-ca", str(ca)]) == 0
    said = capsys.readouterr().out
    assert f"swarm host --name b --connect tls/ROUTER:7447 --auth {tmp_path / 'tls' / 'host-b.json'}" in said
    assert "--listen tls/0.0.0.0:7447" in said
    assert "tcp/" not in said
    assert f"copy {tmp_path / 'tls' / trust.CA} beside each host-NAME.json" in said
    assert "unencrypted" not in said
    assert secure.main(["--hosts", "b", "--out", str(tmp_path / "plain")]) == 0
    plain = capsys.readouterr().out
    assert "--connect tcp/ROUTER:7447" in plain
    assert "tls/" not in plain
    assert "links are plain TCP: each run sends the hosts its agents' passwords, and its data, unencrypted" in plain
    # A host whose login names the CA refuses a plain endpoint off this machine before it connects.
    argv = [
        *PY,
        "host",
        "--connect",
        "tcp/192.0.2.1:7447",
        "--name",
        "b",
        "--auth",
        str(tmp_path / "tls" / "host-b.json"),
        "--workdir",
        str(tmp_path / "work"),
    ]
    res = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 2, res.stdout + res.stderr
    assert "names a CA, for TLS: connect with tls/ROUTER:PORT" in res.stderr
    assert "waiting for a router" not in res.stdout


def test_a_tls_listen_needs_the_tls_files_and_a_loopback_one_is_told_apart() -> None:
    from formation_swarm.launch.launcher import Launch
    from formation_swarm.protocol.session import loopback

    with pytest.raises(ValueError, match=r"a TLS router needs --tls-ca, --tls-cert and --tls-key"):
        Launch("fig11_obstacles", hosts=["a"], listen=f"tls/127.0.0.1:{free_port()}", progress=lambda _l: None)
    assert loopback("tcp/127.0.0.1:7447")
    assert loopback("tcp/[::1]:7447")
    assert loopback("tcp/localhost:7447")
    assert not loopback("tcp/192.168.1.10:7447")
    assert not loopback("tcp/0.0.0.0:7447")


def test_a_host_whose_login_is_another_host_s_says_so_at_start(tmp_path: Path) -> None:
    trust.write_host_logins(tmp_path / "sec", ["c"])
    argv = [
        *PY,
        "host",
        "--connect",
        f"tcp/127.0.0.1:{free_port()}",
        "--name",
        "cc",
        "--auth",
        str(tmp_path / "sec" / "host-c.json"),
        "--workdir",
        str(tmp_path / "work"),
    ]
    res = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 2, res.stdout + res.stderr
    assert "this login is for host c, not for host cc (--name)" in res.stderr
    assert "waiting for a router" not in res.stdout  # refused before it connects
    empty = tmp_path / "empty.json"  # no login at all: it would connect as no one
    empty.write_text("{}")
    empty.chmod(0o600)
    argv[argv.index("--auth") + 1] = str(empty)
    res = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 2, res.stdout + res.stderr
    assert f"--auth {empty}: holds no login (transport/auth/usrpwd): give host-cc.json" in res.stderr


@pytest.mark.slow
def test_a_run_over_tls_on_a_host_started_with_a_relative_auth_path(tmp_path: Path) -> None:
    """The case a relative --auth broke: the host's agents found no CA and never reached the TLS router."""
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make the test's TLS certificates")
    tls = tmp_path / "tls"
    tls.mkdir()
    (tls / "ext.cnf").write_text("subjectAltName=IP:127.0.0.1\n")
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    for argv in (  # the guide's commands (deploy/README.md, "Steps")
        ["req", "-x509", *ec, "-keyout", "ca.key", "-out", "ca.pem", "-days", "1", "-subj", "/CN=swarm test CA"],
        ["req", *ec, "-keyout", "router.key", "-out", "router.csr", "-subj", "/CN=router"],
        [
            "x509",
            "-req",
            "-in",
            "router.csr",
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-out",
            "router.pem",
            "-days",
            "1",
            "-extfile",
            "ext.cnf",
        ],
    ):
        subprocess.run(["openssl", *argv], cwd=tls, check=True, capture_output=True, timeout=30)
    sec = tmp_path / "sec"
    made = subprocess.run(
        [*PY, "secure", "--hosts", "a", "--out", str(sec), "--tls-ca", str(tls / "ca.pem")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert made.returncode == 0, made.stderr
    endpoint = f"tls/127.0.0.1:{free_port()}"
    log = open(tmp_path / "host-a.log", "wb")  # noqa: SIM115 - closed with the process
    host = subprocess.Popen(
        [
            *PY,
            "host",
            "--connect",
            endpoint,
            "--name",
            "a",
            "--auth",
            "host-a.json",
            "--workdir",
            str(tmp_path / "work"),
        ],
        cwd=sec,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    log.close()
    try:
        out = tmp_path / "run"
        argv = [
            *PY,
            "run",
            "fig11_obstacles",
            "--seed",
            "5",
            "--no-logger",
            "--out",
            str(out),
            "--hosts",
            "a",
            "--listen",
            endpoint,
            "--host-logins",
            str(sec / "hosts.txt"),
            "--tls-ca",
            str(tls / "ca.pem"),
            "--tls-cert",
            str(tls / "router.pem"),
            "--tls-key",
            str(tls / "router.key"),
        ]
        run = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
        assert run.returncode == 0, run.stdout + run.stderr + (tmp_path / "host-a.log").read_text()
        summary = json.loads((out / "summary.json").read_text())
        assert summary["placement"] == {"agent-1": "a", "agent-2": "a", "agent-3": "a"}
        assert summary["failure"] is None
        for name in ("agent-1", "agent-2", "agent-3"):
            assert "exit code 0" in (out / "logs" / f"{name}.log").read_text().splitlines()[-1], name
    finally:
        host.terminate()
        assert host.wait(timeout=20) == 0
    deadline = time.monotonic() + 10  # its fork server (whose path names sec/) leaves after it
    while processes(lambda cmd: str(sec) in cmd) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not processes(lambda cmd: str(sec) in cmd)


def test_a_host_clears_the_logins_a_killed_one_left_and_keeps_its_workdir_to_itself(tmp_path: Path) -> None:
    """A host killed mid-run leaves its run's logins in its workdir (a run
    removes its own only when it ends): the next host there removes them.
    Two hosts never share a workdir."""
    sec = trust.write_host_logins(tmp_path / "sec", ["b", "c"])
    work = tmp_path / "work"
    (work / "old-run" / "secrets").mkdir(parents=True)
    (work / "old-run" / "secrets" / "agent-2.json").write_text("{}")
    port = free_port()
    argv = [
        *PY,
        "host",
        "--connect",
        f"tcp/127.0.0.1:{port}",
        "--name",
        "b",
        "--auth",
        str(sec["host-b"]),
        "--workdir",
        str(work),
    ]
    first = subprocess.Popen(argv, stdout=subprocess.PIPE, text=True)
    try:
        assert first.stdout is not None
        said = first.stdout.readline()
        assert said.startswith(f"host b: removed the logins of 1 run(s) a previous host process left in {work}")
        assert not (work / "old-run" / "secrets").exists()
        assert (work / "old-run").is_dir()  # its logs stay
        second = subprocess.run(
            [
                *PY,
                "host",
                "--connect",
                f"tcp/127.0.0.1:{port}",
                "--name",
                "c",
                "--auth",
                str(sec["host-c"]),
                "--workdir",
                str(work),
            ],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert second.returncode == 2, second.stderr
        assert f"--workdir {work} is in use by another swarm host: give each its own" in second.stderr
    finally:
        first.terminate()
        first.wait(timeout=30)
