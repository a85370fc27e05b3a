"""Agents on another host: a network namespace joined to this one by a veth
pair, every process started on its own (``swarm router|world|agent|logger``)
as a user spreading a run over machines would, through a standalone router
started from deploy/router.json5, with the credentials and access rules of
``swarm secure`` and TLS on every link (a CA made here, with openssl).

Needs root, iproute2 (``ip netns``) and openssl; skipped with the reason otherwise.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from formation_swarm.launch.launcher import free_port
from tests.helpers import ROOT, SCENARIOS, reap

FIG11 = SCENARIOS / "fig11_obstacles.toml"
ROUTER_CONFIG = ROOT / "deploy" / "router.json5"


def _tls_files(folder: Path, host_ip: str) -> tuple[Path, Path, Path]:
    """A throw-away CA and a router certificate naming ``host_ip`` and
    127.0.0.1 (where the world, on the router's machine, connects)."""
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make the test's TLS certificates")
    folder.mkdir()
    ca, ca_key, cert, key = (folder / n for n in ("ca.pem", "ca.key", "router.pem", "router.key"))
    ext = folder / "ext.cnf"
    ext.write_text(f"subjectAltName=IP:{host_ip},IP:127.0.0.1\n")
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


def test_agents_in_another_namespace_fly_fig11_through_a_router(robot_host: tuple, tmp_path: Path) -> None:
    ns, host_ip, _ns_ip = robot_host
    port = free_port()
    router = f"tls/{host_ip}:{port}"
    near = f"tls/127.0.0.1:{port}"  # the world's login is granted over the router's loopback only
    run = f"multihost-{uuid.uuid4().hex[:8]}"
    scenario = tmp_path / "scenario.toml"
    shutil.copy(FIG11, scenario)
    py = [sys.executable, "-m"]
    ca, cert, key = _tls_files(tmp_path / "tls", host_ip)
    secure = tmp_path / "secure"
    made = subprocess.run(
        [
            *py,
            "formation_swarm.cli",
            "secure",
            str(scenario),
            "--run",
            run,
            "--out",
            str(secure),
            "--tls-ca",
            str(ca),
            "--tls-cert",
            str(cert),
            "--tls-key",
            str(key),
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert made.returncode == 0, made.stderr
    procs: dict[str, subprocess.Popen[bytes]] = {}

    def start(name: str, argv: list[str]) -> None:
        log = open(tmp_path / f"{name}.log", "wb")  # noqa: SIM115 - closed with the process
        procs[name] = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        log.close()

    def auth(user: str) -> list[str]:
        return ["--auth", str(secure / f"{user}.json")]

    common = ["--scenario", str(scenario), "--run", run]
    try:
        start(
            "router",
            [
                *py,
                "formation_swarm.nodes.router",
                "--config",
                str(ROUTER_CONFIG),
                *("--listen", router, "--listen", near),
                *auth("router"),
            ],
        )
        start(
            "world",
            [
                *py,
                "formation_swarm.nodes.world.main",
                *common,
                "--stats",
                str(tmp_path / "world.json"),
                "--zenoh-mode",
                "client",
                "--connect",
                near,
                "--expect-logger",
                "--out",
                str(tmp_path / "run"),
                *auth("world"),
            ],
        )
        start(
            "logger",
            [
                *py,
                "formation_swarm.nodes.logger.main",
                *common,
                "--out",
                str(tmp_path / "recording.rrd"),
                "--stats",
                str(tmp_path / "logger.json"),
                "--connect",
                router,
                *auth("logger"),
            ],
        )
        for rid in (1, 2, 3):
            agent = [*py, "formation_swarm.nodes.agent.main", "--id", str(rid), *common, *auth(f"agent-{rid}")]
            start(
                f"agent-{rid}",
                [
                    "ip",
                    "netns",
                    "exec",
                    ns,
                    *agent,
                    "--stats",
                    str(tmp_path / f"agent-{rid}.json"),
                    "--connect",
                    router,
                ],
            )
        # From the robots' host, a client that trusts the CA but has no login is refused.
        rogue = (
            "import sys, zenoh\n"
            "from formation_swarm.protocol.session import make_config\n"
            f"conf = make_config('client', [{router!r}], connect_timeout_s=3.0,\n"
            f"    settings={{'transport/link/tls/root_ca_certificate': {str(ca)!r}}})\n"
            "try:\n    zenoh.open(conf)\n"
            "except zenoh.ZError as exc:\n    print('refused:', exc); sys.exit(7)\n"
        )
        refused = subprocess.run(
            ["ip", "netns", "exec", ns, sys.executable, "-c", rogue],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert refused.returncode == 7, refused.stdout + refused.stderr
        assert "Unable to connect" in refused.stdout
        assert procs["world"].wait(timeout=180) == 0, (tmp_path / "world.log").read_text()
        for name in ("agent-1", "agent-2", "agent-3", "logger"):
            assert procs[name].wait(timeout=10) == 0, (tmp_path / f"{name}.log").read_text()
        world = json.loads((tmp_path / "world.json").read_text())
        assert world["ticks"] == 1120 or world["leader_done"]
        assert world["lockstep_misses"] == 0
        assert world["collisions"] == 0
        for rid in (1, 2, 3):  # triangle -> line before the obstacles -> triangle after
            assert [e["formation"] for e in world["formation_events"] if e["robot"] == rid] == ["line", "triangle"]
        for rid in (1, 2, 3):
            agent = json.loads((tmp_path / f"agent-{rid}.json").read_text())
            assert agent["answered"] == world["ticks"]
        # The logger, on this host, recorded every tick of both followers in the other.
        logger = json.loads((tmp_path / "logger.json").read_text())
        assert logger["messages"]["telemetry"] == 2 * world["ticks"]
        assert logger["messages"]["truth"] == world["ticks"]
        assert (tmp_path / "recording.rrd").stat().st_size > 10_000
        # The world's summary says why the run ended; every process's last line says it ended.
        summary = json.loads((tmp_path / "run" / "summary.json").read_text())
        assert summary["end_reason"] == ("leader_finished" if world["leader_done"] else "duration_reached")
        assert summary["ticks"] == world["ticks"]
        for name in ("world", "logger", "agent-1", "agent-2", "agent-3"):
            last = (tmp_path / f"{name}.log").read_text().splitlines()[-1]
            assert f"run {run} ended (" in last, (name, last)
            assert "exit code 0" in last, (name, last)
    finally:
        reap(procs.values())
