"""Mutual TLS across hosts: the robots in a network namespace joined to this
one by a veth pair, every process started on its own with the files of
``swarm secure --mtls`` (a certificate per login, the router's rules on the
certificates' common names), through a router started from
deploy/router.json5.

While Fig. 11 flies to its end, clients on the robots' host try the router:
without a certificate, or with one of another CA, they are refused at the
handshake; with agent 2's password and a certificate of another name (robot
3's, or ``intruder`` from the run's own CA) they connect, hold agent 2's
token, put on robot 2's command key every 50 ms and subscribe to its inbox,
and none of it counts: they receive nothing, the run's observer sees none
of their puts, and the run ends as a run without them does. The world's
own login and certificate, from the robots' host, are granted nothing
either: its forged "done" ends nothing, and the world connects over the
router's loopback.

Needs root, iproute2 (``ip netns``) and openssl; skipped with the reason otherwise.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import threading
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest

from formation_swarm.launch import certs
from formation_swarm.launch.launcher import Launch, free_port
from formation_swarm.protocol import tls, trust
from tests.helpers import ROOT, SCENARIOS, reap

FIG11 = SCENARIOS / "fig11_obstacles.toml"
FIG11_TICKS = 1061  # the leader's last waypoint, seed 1 (tests/system/test_packaging.py)
ROUTER_CONFIG = ROOT / "deploy" / "router.json5"
PROBE = Path(__file__).with_name("mtls_probe.py")
PY = [sys.executable, "-m"]


def _secure(tmp_path: Path, run: str, host_ip: str) -> tuple[Path, Path, Path]:
    """The run's files (``swarm secure --mtls`` with a CA of the test's, whose
    key then signs ``intruder``); that certificate; a CA foreign to the run."""
    if certs.openssl_missing():
        pytest.skip("needs openssl to make the certificates")
    pki = tmp_path / "pki"
    pki.mkdir()
    ca, ca_key = certs.make_ca(pki, "the test's CA")
    secure = tmp_path / "secure"
    argv = [str(FIG11), "--run", run, "--out", str(secure), "--mtls", "--router-address", host_ip, "--observer"]
    made = subprocess.run(
        [*PY, "formation_swarm.cli", "secure", *argv, "--tls-ca", str(ca), "--tls-ca-key", str(ca_key)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert made.returncode == 0, made.stderr
    intruder, _ = certs.make_certificate(pki, "intruder", (ca, ca_key))
    other = tmp_path / "other"
    other.mkdir()
    foreign, _ = certs.make_certificate(other, "agent-2", certs.make_ca(other, "another CA"))
    return secure, intruder, foreign


def _login(secure: Path, user: str, certificate: Path | None = None, *, mtls: bool = True) -> dict[str, Any]:
    """``user``'s login with its own certificate, ``certificate`` (and its key)
    instead, or (``mtls=False``) none."""
    settings = trust.read_settings(secure / f"{user}.json")
    if certificate is not None:
        settings[tls.CONNECT_CERTIFICATE] = str(certificate)
        settings[tls.CONNECT_PRIVATE_KEY] = str(certificate.with_suffix(".key"))
    if not mtls:
        for key in (tls.CONNECT_CERTIFICATE, tls.CONNECT_PRIVATE_KEY, tls.ENABLE_MTLS):
            del settings[key]
    return settings


def _read_line(proc: subprocess.Popen[str], timeout_s: float) -> str:
    """The probe's next line of stdout, within ``timeout_s``."""
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(proc.stdout.readline()), daemon=True)
    reader.start()
    reader.join(timeout_s)
    return got[0] if got else ""


@pytest.mark.slow
def test_a_wrong_certificate_name_gets_nothing_and_the_right_ones_fly_fig11(robot_host: tuple, tmp_path: Path) -> None:
    ns, host_ip, _ns_ip = robot_host
    port = free_port()
    router = f"tls/{host_ip}:{port}"
    near = f"tls/127.0.0.1:{port}"  # the world's login is granted over the router's loopback only
    run = f"mtls-{uuid.uuid4().hex[:8]}"
    scenario = tmp_path / "scenario.toml"
    shutil.copy(FIG11, scenario)
    secure, intruder, foreign = _secure(tmp_path, run, host_ip)
    plan = {
        "endpoint": router,
        "run": run,
        "robot": 2,
        "refused": {
            "no certificate": _login(secure, "agent-2", mtls=False),
            "agent-2 of another CA": _login(secure, "agent-2", foreign),
        },
        "wrong": {
            "agent-3's certificate": _login(secure, "agent-2", secure / "agent-3.pem"),
            "intruder of the run's CA": _login(secure, "agent-2", intruder),
        },
        "world": _login(secure, "world"),
        "observer": _login(secure, "observer"),
        "budget_s": 600,
    }
    (tmp_path / "plan.json").write_text(json.dumps(plan))
    procs: dict[str, subprocess.Popen[Any]] = {}

    def start(name: str, argv: list[str], where: Sequence[str] = ()) -> None:
        log = open(tmp_path / f"{name}.log", "wb")  # noqa: SIM115 - closed with the process
        procs[name] = subprocess.Popen([*where, *argv], stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        log.close()

    def auth(user: str) -> list[str]:
        return ["--auth", str(secure / f"{user}.json")]

    def stats(name: str) -> list[str]:
        return ["--stats", str(tmp_path / f"{name}.json"), "--connect", router]

    robots_host = ["ip", "netns", "exec", ns]
    common = ["--scenario", str(scenario), "--run", run]
    try:
        listen = ["--config", str(ROUTER_CONFIG), "--listen", router, "--listen", near]
        start("router", [*PY, "formation_swarm.nodes.router", *listen, *auth("router")])
        with open(tmp_path / "probe.err", "wb") as err:
            probe = subprocess.Popen(
                [*robots_host, sys.executable, str(PROBE), str(tmp_path / "plan.json")],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=err,
                text=True,
            )
        procs["probe"] = probe
        # The wrong clients are connected (holding agent 2's token) before agent 2 starts.
        connected = _read_line(probe, 120)
        assert json.loads(connected or "{}") == {"connected": 4}, (tmp_path / "probe.err").read_text()
        as_client = ["--zenoh-mode", "client", "--expect-logger", "--out", str(tmp_path / "run")]
        world = [*common, "--stats", str(tmp_path / "world.json"), "--connect", near, *as_client, *auth("world")]
        start("world", [*PY, "formation_swarm.nodes.world.main", *world])
        logger = ["--out", str(tmp_path / "recording.rrd")]
        start("logger", [*PY, "formation_swarm.nodes.logger.main", *common, *stats("logger"), *logger, *auth("logger")])
        for rid in (1, 2, 3):
            agent = [*PY, "formation_swarm.nodes.agent.main", "--id", str(rid), *common, *auth(f"agent-{rid}")]
            start(f"agent-{rid}", [*agent, *stats(f"agent-{rid}")], robots_host)
        assert procs["world"].wait(timeout=300) == 0, (tmp_path / "world.log").read_text()
        for name in ("agent-1", "agent-2", "agent-3", "logger"):
            assert procs[name].wait(timeout=30) == 0, (tmp_path / f"{name}.log").read_text()
        out, _ = probe.communicate(timeout=60)  # stdin closed: the probe stops and reports
        assert probe.returncode == 0, (tmp_path / "probe.err").read_text()
        seen = json.loads(out.strip().splitlines()[-1])
    finally:
        reap(procs.values())
    (tmp_path / "seen.json").write_text(json.dumps(seen, indent=1))
    print(json.dumps(seen))  # the figures, for a reader of the test's output (-s)

    # Refused at the handshake, within the probe's 3 s connect timeout.
    for name, tried in seen["refused"].items():
        assert tried["opened"] is False, name
        assert "Unable to connect" in tried["error"], (name, tried)
    # Connected with agent 2's password, granted nothing, for the whole run.
    world = json.loads((tmp_path / "world.json").read_text())
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["end_reason"] == "leader_finished"
    assert summary["ticks"] == world["ticks"] == FIG11_TICKS
    assert set(seen["wrong"]) == {"agent-3's certificate", "intruder of the run's CA", "world from afar"}
    for name, got in seen["wrong"].items():
        assert got["received"] == 0, name
        assert got["puts"] > 20, name  # it kept trying, every 50 ms, the whole run long
    assert seen["observer"]["wrong_puts"] == 0
    assert seen["observer"]["observations"] >= FIG11_TICKS  # the right certificates heard every tick
    # The run as without them: no miss, no rejection, the formation changes, robot 2 answered every tick.
    assert world["lockstep_misses"] == 0
    assert world["collisions"] == 0
    assert sum(world["rejected"].values()) == 0, world["rejected"]
    for rid in (1, 2, 3):
        assert [e["formation"] for e in world["formation_events"] if e["robot"] == rid] == ["line", "triangle"]
        agent = json.loads((tmp_path / f"agent-{rid}.json").read_text())
        assert agent["answered"] == FIG11_TICKS
    for name in ("world", "logger", "agent-1", "agent-2", "agent-3"):
        last = (tmp_path / f"{name}.log").read_text().splitlines()[-1]
        assert f"run {run} ended (" in last, (name, last)
        assert "exit code 0" in last, (name, last)
    # Every robot flew as in a local run of the scenario, without them.
    with Launch(FIG11, out=tmp_path / "clean", logger=False, progress=lambda _l: None) as clean:
        assert summary["robot_digests"] == clean.wait(timeout_s=240).summary["robot_digests"]
