"""``swarm host`` and ``swarm run --hosts`` on one machine (loopback): the
request decoder, the host logins' access rules, a run placed on two hosts
(same trajectory digest as a local run, a full run folder) and a host that
dies mid-run (its robots counted dead, its agents gone, a non-zero exit that
names it). tests/hosts/test_hosts_netns.py does the same across network
namespaces; tests/hosts/test_host_setup.py checks a host's set-up."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import time
import uuid
from pathlib import Path

import msgpack
import pytest
import zenoh

from formation_swarm import __version__
from formation_swarm.launch.launcher import free_port
from formation_swarm.launch.remote import place
from formation_swarm.protocol import trust
from formation_swarm.protocol.codec import DecodeError
from formation_swarm.protocol.hostmsg import MAX_HOST_MESSAGE_BYTES, HostReply, HostRequest
from formation_swarm.protocol.keys import HostKeys
from formation_swarm.protocol.session import make_config
from tests.helpers import Console
from tests.hosts.local_hosts import PY, Hosts, agents_of, alive, summary_placement


# -- the wire -----------------------------------------------------------------------
def test_a_request_round_trips_and_bad_ones_are_refused_with_a_reason() -> None:
    req = HostRequest(
        "start",
        __version__,
        run="r1",
        process="agent-3.2",
        scenario="x = 1",
        user="agent-3",
        password="p" * 32,
        world_grace_s=1.0,
        lockstep=True,
    )
    assert HostRequest.from_bytes(req.to_bytes()) == req
    good = msgpack.unpackb(req.to_bytes())
    cases = {
        b"\xc1": "not msgpack",
        msgpack.packb([1, 2]): "wrong type",
        msgpack.packb({**good, "extra": 1}): "unknown field",
        msgpack.packb({k: v for k, v in good.items() if k != "run"}): "missing field",
        msgpack.packb({**good, "op": "format-disk"}): "unknown op",
        msgpack.packb({**good, "run": "../etc"}): "bad run id",
        msgpack.packb({**good, "process": "world"}): "bad process",
        msgpack.packb({**good, "world_grace_s": float("nan")}): "out of range",
        msgpack.packb({**good, "user": 7}): "wrong type",
        msgpack.packb({**good, "lockstep": 1}): "wrong type",
        msgpack.packb({**good, "op": "signal", "action": "reboot"}): "bad action",
        b"\x00" * (MAX_HOST_MESSAGE_BYTES + 1): "oversized",
    }
    for payload, reason in cases.items():
        with pytest.raises(DecodeError) as info:
            HostRequest.from_bytes(payload)
        assert info.value.reason == reason, (payload[:40], info.value)
    reply = HostReply(ok=True, version="1", host="a", processes=(("agent-2", 10, None), ("agent-3", 11, -9)))
    assert HostReply.from_bytes(reply.to_bytes()) == reply
    bad = msgpack.packb({**msgpack.unpackb(reply.to_bytes()), "processes": [["rm -rf", 1, 0]]})
    with pytest.raises(DecodeError, match="not agent-N"):
        HostReply.from_bytes(bad)


def test_robots_are_placed_explicitly_then_round_robin_within_what_each_host_may_run() -> None:
    assert place([1, 2, 3], ["a", "b"], {"a": None, "b": None}, {}) == {1: "a", 2: "b", 3: "a"}
    assert place([1, 2, 3], ["a", "b"], {"a": None, "b": None}, {1: "b"}) == {1: "b", 2: "a", 3: "b"}
    assert place([1, 2, 3], ["a", "b"], {"a": (1,), "b": None}, {}) == {1: "a", 2: "b", 3: "b"}
    with pytest.raises(ValueError, match="no host of a, b may run robot 3"):
        place([1, 2, 3], ["a", "b"], {"a": (1,), "b": (2,)}, {})
    with pytest.raises(ValueError, match="may only run robots 1"):
        place([1, 2], ["a", "b"], {"a": (1,), "b": None}, {2: "a"})


# -- the walls ----------------------------------------------------------------------
def test_a_host_login_answers_on_its_own_key_only_and_hears_nothing_of_the_run(tmp_path: Path) -> None:
    run = f"hosts-{uuid.uuid4().hex[:8]}"
    hosts = trust.write_host_logins(tmp_path / "hosts", ["a", "b"])
    logins = trust.read_host_logins(hosts[trust.HOST_LOGINS], ["a", "b"])
    files = trust.write_run_secrets(tmp_path / "run", run, (1, 2, 3), 1, world="loopback", host_logins=logins)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    sessions: list[zenoh.Session] = []

    def open_as(settings_file: Path, mode: str = "client") -> zenoh.Session:
        settings = trust.read_settings(settings_file)
        conf = make_config(
            mode,
            [] if mode == "router" else [endpoint],
            listen=[endpoint] if mode == "router" else [],
            connect_timeout_s=3.0,
            settings=settings,
        )
        sessions.append(zenoh.open(conf))
        return sessions[-1]

    try:
        open_as(files["router"], "router")
        launcher = open_as(files["launcher"])
        host_a = open_as(hosts["host-a"])
        answered: list[str] = []
        for key in (HostKeys("a").ctl, HostKeys("b").ctl):  # a's login serves its key, and tries b's
            host_a.declare_queryable(key, lambda q: (answered.append(str(q.key_expr)), q.reply(q.key_expr, b"x")))
        heard: list[str] = []
        host_a.declare_subscriber(f"swarm/{run}/**", lambda s: heard.append(str(s.key_expr)))
        world = open_as(files["world"])

        def ask(key: str) -> list[bytes]:
            return [r.ok.payload.to_bytes() for r in launcher.get(key, timeout=1.0) if r.ok is not None]

        deadline = time.monotonic() + 5
        while not ask(HostKeys("a").ctl) and time.monotonic() < deadline:
            pass
        assert ask(HostKeys("a").ctl) == [b"x"]
        assert ask(HostKeys("b").ctl) == []  # the router never forwards b's queries to a's login
        assert answered
        assert all(k == HostKeys("a").ctl for k in answered)
        world.put(f"swarm/{run}/world/truth", b"t")
        # The agents log in with their own logins: a host's hears nothing of the run.
        time.sleep(0.3)  # nothing to wait for: asserting an absence
        assert heard == []
    finally:
        for s in reversed(sessions):
            s.close()


# -- runs on hosts ------------------------------------------------------------------


@pytest.mark.slow
def test_a_run_on_two_hosts_is_the_local_run_and_leaves_a_full_folder(two_hosts: Hosts, tmp_path: Path) -> None:
    local = subprocess.run(
        [*PY, "run", "fig11_obstacles", "--seed", "5", "--no-logger", "--out", str(tmp_path / "l")],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert local.returncode == 0, local.stdout + local.stderr
    out = tmp_path / "placed"
    run = subprocess.run(two_hosts.run_argv(out, "a,b"), capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "agent-2 on host b" in run.stdout
    summary = json.loads((out / "summary.json").read_text())
    local_summary = json.loads((tmp_path / "l" / "summary.json").read_text())
    assert summary["trajectory_digest"] == local_summary["trajectory_digest"]
    assert summary["placement"] == {"agent-1": "a", "agent-2": "b", "agent-3": "a"}
    assert summary["hosts"]["b"]["version"] == __version__
    assert not summary["hosts"]["b"]["lost"]
    assert summary["processes"]["agent-2"]["host"] == "b"
    assert summary["processes"]["world"]["host"] == "local"
    for name in ("world", "logger", "agent-1", "agent-2", "agent-3"):
        assert "exit code 0" in (out / "logs" / f"{name}.log").read_text().splitlines()[-1], name
        assert (out / "stats" / f"{name}.json").is_file(), name
    agent2 = json.loads((out / "stats" / "agent-2.json").read_text())
    assert agent2["answered"] == summary["ticks"]
    # A lockstep run's telemetry waits for the logger on a host too: none of it is dropped.
    assert all(json.loads((out / "stats" / f"agent-{r}.json").read_text())["lockstep"] for r in (1, 2, 3))
    assert (out / "recording.rrd").stat().st_size > 10_000
    assert not (out / "secrets").exists()
    # Each host ended the run: its agents reaped, their logins deleted, the hosts still serving.
    for n in ("a", "b"):
        assert "ended (the launcher ended it)" in two_hosts.log(n)
        assert two_hosts.procs[n].poll() is None
        assert not list((tmp_path / f"work-{n}").glob("*/secrets"))


@pytest.mark.slow
def test_a_host_that_dies_mid_run_has_its_robots_counted_dead_and_fails_the_run(
    two_hosts: Hosts, tmp_path: Path
) -> None:
    out = tmp_path / "lost"
    run = Console(two_hosts.run_argv(out, "a,b"), "[swarm] tick ")
    try:
        assert run.seen.wait(120), run.text
        b_agents = agents_of(two_hosts.procs["b"].pid)
        assert b_agents, "no agent of host b found"
        os.kill(two_hosts.procs["b"].pid, signal.SIGKILL)  # the host, not its agents
        code = run.wait(180)
    finally:
        run.close()
    text = run.text
    assert code == 1, text
    assert "host b was lost" in text, text
    assert "robots (2) were counted dead" in text, text
    assert "(its token went): robot 2 counted dead" in text, text
    # Its follower's error until then, as for a killed agent (the figures after are of a robot nobody drives).
    assert "follower R2: formation error RMS" in text
    assert "until its agent was lost at t=" in text, text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["hosts"]["b"]["lost"] is True
    assert any(e["event"] == "host lost" and e["host"] == "b" and e["robots"] == [2] for e in summary["events"])
    assert [d["robot"] for d in summary["deaths"]] == [2]  # the world saw robot 2's agent go
    assert summary["failure"].startswith("host b lost at sim t=")
    assert summary["failure"].endswith(": robot 2 counted dead")
    assert summary["processes"]["agent-2"]["exit_code"] is None  # it stayed on host b
    assert summary["processes"]["agent-2"]["lost_with_host"] == "b"
    assert "agent-2 exited with code 255" not in text
    # Its agents died with it (they are forked by its spawner, which dies with it).
    deadline = time.monotonic() + 10
    while any(Path(f"/proc/{p}").exists() and alive(p) for p in b_agents) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [p for p in b_agents if alive(p)]
    assert (out / "logs" / "agent-1.log").is_file()  # host a's agents were fetched


@pytest.mark.slow
def test_process_faults_on_a_remote_agent_are_executed_by_its_host(two_hosts: Hosts, tmp_path: Path) -> None:
    out = tmp_path / "faults"
    # Every robot on b: a runs none, which the launcher warns of.
    argv = [
        *two_hosts.run_argv(out, "a,b"),
        "--place",
        "1=b,2=b,3=b",
        "--fault",
        "restart agent-2@5s after=1s",
        "--fault",
        "freeze agent-3@10s for=1s",
    ]
    run = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "[swarm] warning: host a runs no robot (the placement gave them none)" in run.stdout
    assert summary_placement(out) == {"agent-1": "b", "agent-2": "b", "agent-3": "b"}
    summary = json.loads((out / "summary.json").read_text())
    done = [
        (e["event"], e["process"]) for e in summary["events"] if e["event"] in ("killed", "started", "frozen", "thawed")
    ]
    assert done == [("killed", "agent-2"), ("started", "agent-2.2"), ("frozen", "agent-3"), ("thawed", "agent-3")]
    assert summary["processes"]["agent-2.2"]["host"] == "b"  # restarted where it ran
    assert "exit code 0" in (out / "logs" / "agent-2.2.log").read_text().splitlines()[-1]
    assert json.loads((out / "stats" / "agent-2.2.json").read_text())["answered"] > 0
    assert "run " in two_hosts.log("b")
    assert "started agent-2.2" in two_hosts.log("b")


@pytest.mark.slow
@pytest.mark.parametrize("hosts", ["two_hosts", "two_tls_hosts"])
def test_the_hosts_stop_a_run_s_agents_when_its_launcher_dies(
    hosts: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    two_hosts: Hosts = request.getfixturevalue(hosts)
    out = tmp_path / "orphan"
    argv = [*two_hosts.run_argv(out, "a,b"), "--mode", "realtime"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert proc.stdout is not None
        deadline = time.monotonic() + 120
        for line in proc.stdout:  # the run is going once the launcher says a tick
            if "[swarm] tick " in line or time.monotonic() > deadline:
                break
        agents = agents_of(two_hosts.procs["a"].pid) + agents_of(two_hosts.procs["b"].pid)
        assert len(agents) == 3, agents
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    deadline = time.monotonic() + 20
    while [p for p in agents if alive(p)] and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [p for p in agents if alive(p)]
    for n in ("a", "b"):
        while "its launcher's token went" not in two_hosts.log(n) and time.monotonic() < deadline + 10:
            time.sleep(0.05)
        assert "its launcher's token went" in two_hosts.log(n), two_hosts.log(n)
        assert two_hosts.procs[n].poll() is None  # still serving
    # The killed launcher could not remove the run's secrets; what outlasts the run
    # (the hosts' logins in the router's password list, the copy of its TLS key)
    # was gone once the router read it.
    left = sorted(p.name for p in (out / "secrets").iterdir())
    assert "passwords.txt" not in left, left
    assert "router.key" not in left, left
    assert ("router.pem" in left) == (two_hosts.tls is not None), left  # a TLS run's, and its key is gone
    lasting = [line.split(":", 1)[1] for line in (two_hosts.tmp / "sec" / "hosts.txt").read_text().splitlines()]
    assert len(lasting) == 2
    if two_hosts.tls is not None:
        lasting.append((two_hosts.tls / "router.key").read_text())
    assert not any(pw in p.read_text() for p in (out / "secrets").iterdir() for pw in lasting), left


def test_doctor_hears_the_hosts_then_names_the_one_that_went(two_hosts: Hosts, tmp_path: Path) -> None:
    argv = [
        *PY,
        "doctor",
        "--listen",
        two_hosts.endpoint,
        "--hosts",
        "a,b",
        "--scenario",
        "fig11_obstacles",
        "--host-logins",
        str(tmp_path / "sec" / "hosts.txt"),
        "--timeout",
        "30",
    ]
    ok = subprocess.run(argv, capture_output=True, text=True, timeout=120, check=False)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    lines = ok.stdout.splitlines()
    for h in ("a", "b"):
        line = next(x for x in lines if x.startswith(f"  host {h}: heard; round trip "))
        assert f"version {__version__}" in line
        assert abs(float(line.split("clock ")[1].split(" ms")[0])) < 1000  # one machine, one clock
    assert "  placement: robot 1 -> a, robot 2 -> b, robot 3 -> a" in lines
    assert lines[-1] == "verdict: OK: a run on hosts a, b would start"
    two_hosts.procs["b"].terminate()
    two_hosts.procs["b"].wait(timeout=10)
    argv[argv.index("--timeout") + 1] = "3"
    bad = subprocess.run(argv, capture_output=True, text=True, timeout=120, check=False)
    assert bad.returncode == 1, bad.stdout + bad.stderr
    verdict = bad.stdout.splitlines()[-1]
    assert verdict.startswith("verdict: FAIL: ")
    assert "host b not heard" in verdict


def test_a_run_whose_host_never_comes_stops_at_the_deadline_naming_it(two_hosts: Hosts, tmp_path: Path) -> None:
    two_hosts.procs["b"].terminate()
    two_hosts.procs["b"].wait(timeout=10)
    out = tmp_path / "missing"
    started = time.monotonic()
    run = subprocess.run(
        [*two_hosts.run_argv(out, "a,b"), "--hosts-timeout", "3"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 1, run.stdout + run.stderr
    # b at least (a too if it had not reconnected yet: hosts retry their router with a back-off)
    assert re.search(
        rf"\[swarm\] waiting up to 3 s for hosts? (a, )?b to connect to {re.escape(two_hosts.endpoint)}", run.stdout
    ), run.stdout
    assert "swarm run: host b did not connect to " in run.stderr
    assert "within 3 s" in run.stderr
    assert time.monotonic() - started < 60
    summary = json.loads((out / "summary.json").read_text())
    assert summary["exit_code"] == 1
    assert any(e["event"] == "start failed" and "host b did not connect" in e["why"] for e in summary["events"])
    # Said as what happened: no process failed, the run never started.
    assert summary["end_reason"] == "start_failed"
    assert summary["ended"].startswith("the run could not start: host b did not connect to "), summary["ended"]
    assert summary["failure"] == summary["ended"]
    assert "started agent" not in two_hosts.log("a")  # every host is waited for before any agent starts
