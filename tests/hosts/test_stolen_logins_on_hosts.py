"""What a stolen login achieves at worst in a run placed on hosts.

A host's login may serve its own key, swarmhost/NAME/ctl, and nothing else
(tests/hosts/test_hosts.py). A thief with it can answer the launcher's
requests as that host would. The launcher asks every session on the key
(remote.HostClient.ask): a host answering from two sessions at the run's
start is left out (neither can be told to be the real one, so neither is
sent an agent's login) and its robots fly on the other hosts; once a host
has answered, another session's answers are refused and counted, and the
run flies as without it.

The world's and the logger's logins of such a run are granted their keys
over loopback only (both run beside the launcher, the router): from another
interface they are granted nothing.
"""

from __future__ import annotations

import json
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import pytest
import zenoh

from formation_swarm import __version__
from formation_swarm.launch.launcher import Launch
from formation_swarm.protocol import trust
from formation_swarm.protocol.hostmsg import HostReply, HostRequest
from formation_swarm.protocol.keys import HostKeys, Keys
from formation_swarm.protocol.messages import Status
from formation_swarm.protocol.session import make_config
from tests.helpers import SCENARIOS, Console, outward_address
from tests.hosts.local_hosts import PY, Hosts

pytestmark = pytest.mark.slow

# 2,400 ticks: a run still going when the rogue has connected and been asked.
LONG = ["--set", "run.duration_s=120", "--set", "leader.waypoints=[[0, 0], [0, 1000]]"]


class RogueHost:
    """A session on host ``name``'s login that answers its key as that host
    would, falsely: every request done, agent-2 exited with code 1."""

    def __init__(self, hosts: Hosts, name: str) -> None:
        self.name = name
        self.asked: list[str] = []
        self.lock = threading.Lock()
        settings = trust.read_settings(hosts.tmp / "sec" / f"host-{name}.json")
        conf = make_config("client", [hosts.endpoint], connect_timeout_s=60.0, settings=settings)
        self.session = zenoh.open(conf)
        self.queryable = self.session.declare_queryable(HostKeys(name).ctl, self._answer)

    def _answer(self, query: zenoh.Query) -> None:
        req = HostRequest.from_bytes(query.payload.to_bytes())  # type: ignore[union-attr]
        with self.lock:
            self.asked.append(req.op)
        lie = HostReply(
            ok=True, version=__version__, host=self.name, hostname="rogue", processes=(("agent-2", 4242, 1),), code=1
        )
        query.reply(query.key_expr, lie.to_bytes())

    def __enter__(self) -> RogueHost:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.session.close()


def _local(out: Path, *flags: str) -> dict[str, Any]:
    """The summary of the same run on this machine alone: the digests a placed
    run must have (tests/hosts/test_hosts.py: placed and local runs are equal)."""
    argv = [*PY, "run", "fig11_obstacles", "--seed", "5", *flags, "--no-logger", "--out", str(out)]
    local = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
    assert local.returncode == 0, local.stdout + local.stderr
    return json.loads((out / "summary.json").read_text())


def test_a_host_whose_login_answers_twice_at_the_start_is_left_out_and_sent_no_login(
    two_hosts: Hosts, tmp_path: Path
) -> None:
    two_hosts.procs["b"].terminate()
    two_hosts.procs["b"].wait(timeout=10)
    out, alone = tmp_path / "twice", tmp_path / "alone"
    run = Console([*two_hosts.run_argv(out, "a,b"), "--hosts-timeout", "60"], "waiting up to 60 s for host")
    try:
        with RogueHost(two_hosts, "b") as rogue:  # connects once the run's router is up: before host b
            two_hosts.start("b")
            code = run.wait(240)
            asked = list(rogue.asked)
            only_b = Console([*two_hosts.run_argv(alone, "b"), "--hosts-timeout", "60"], "no marker")
            code_only_b = only_b.wait(120)
    finally:
        run.close()
    text = run.text
    # Host b is left out; its robot flies on a, as in a clean run.
    assert code == 0, text
    assert "[swarm] warning: host b answered from 2 sessions on its login" in text, text
    assert "make new host logins (swarm secure --hosts)" in text
    assert "host b is left out of this run" in text
    assert "  event: host b left out of the run: its login answered from two sessions\n" in text
    assert asked == ["info"]  # asked who it is, and nothing more: never a start, which carries an agent's login
    summary = json.loads((out / "summary.json").read_text())
    assert summary["placement"] == {"agent-1": "a", "agent-2": "a", "agent-3": "a"}
    assert summary["ticks"] == 1061
    assert summary["end_reason"] == "leader_finished"
    assert summary["robot_digests"] == _local(tmp_path / "local")["robot_digests"]
    assert [e["host"] for e in summary["events"] if e["event"] == "host left out"] == ["b"]
    assert "started agent" not in two_hosts.log("b")
    # With no other host to take its robots, the run does not start.
    assert code_only_b == 1, only_b.text
    assert "no other host is left" in only_b.text, only_b.text
    assert json.loads((alone / "summary.json").read_text())["end_reason"] == "start_failed"
    assert "started agent" not in two_hosts.log("b")


def test_a_second_session_on_a_hosts_login_mid_run_is_refused_and_counted(two_hosts: Hosts, tmp_path: Path) -> None:
    clean = _local(tmp_path / "l", *LONG)
    out = tmp_path / "placed"
    run = Console([*two_hosts.run_argv(out, "a,b"), *LONG], "[swarm] agent-3 on host")
    try:
        assert run.seen.wait(120), run.text
        with RogueHost(two_hosts, "b") as rogue:
            deadline = time.monotonic() + 30
            while not rogue.asked and run.proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            asked_while_running = list(rogue.asked) if run.proc.poll() is None else []
            code = run.wait(240)
    finally:
        run.close()
    text = run.text
    assert asked_while_running, f"the rogue was asked nothing while the run went on:\n{text}"
    assert code == 0, text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ticks"] == clean["ticks"]
    assert summary["end_reason"] == clean["end_reason"]
    assert summary["robot_digests"] == clean["robot_digests"]
    assert summary["hosts"]["b"]["hostname"] != "rogue"
    refused = summary["hosts"]["b"]["rejected"]["another session on the host's login"]
    assert refused >= len(asked_while_running), summary["hosts"]["b"]
    said = [e for e in summary["events"] if e["event"] == "host login used twice"]
    assert [(e["host"], e["answers_refused"]) for e in said] == [("b", refused)]
    assert f"[swarm] warning: host b's login answered from another session too during the run ({refused} " in text
    assert f"  event: host b's login answered from another session too: {refused} answers refused\n" in text
    assert summary["processes"]["agent-2"]["exit_code"] == 0  # not the rogue's 1
    assert summary["hosts"]["a"]["rejected"] == {}


def test_a_placed_runs_world_and_logger_logins_are_granted_nothing_from_another_interface(
    two_hosts: Hosts, tmp_path: Path
) -> None:
    outward = outward_address()
    if outward is None:
        pytest.skip("no network interface but loopback: nothing to reach the router from")
    port = two_hosts.endpoint.rsplit(":", 1)[1]
    options = {
        "hosts": ["a", "b"],
        "listen": f"tcp/0.0.0.0:{port}",  # the hosts come over loopback, the thief over its interface
        "host_logins": two_hosts.tmp / "sec" / "hosts.txt",
        "logger": False,
        "overrides": {"run.duration_s": 120.0, "leader.waypoints": [[0.0, 0.0], [0.0, 1000.0]]},
    }
    fig11 = SCENARIOS / "fig11_obstacles.toml"
    heard: dict[str, list[str]] = {"loopback": [], "outward": [], "logger loopback": [], "logger outward": []}
    with Launch(fig11, out=tmp_path / "run", progress=lambda _l: None, **options) as launch:
        assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=120)
        k = Keys(launch.run_id)
        sessions = {
            f"{prefix}{where}": zenoh.open(
                make_config("client", [f"tcp/{address}:{port}"], connect_timeout_s=10.0, settings=launch.login(user))
            )
            for prefix, user in (("", "world"), ("logger ", "logger"))  # the logger's login, though no logger runs
            for where, address in (("outward", outward), ("loopback", "127.0.0.1"))  # outward heard first, if at all
        }
        try:
            for where, sess in sessions.items():
                key = k.world_all if where.startswith("logger") else k.all_cmd  # what each hears of the run
                sess.declare_subscriber(key, lambda s, w=where: heard[w].append(str(s.key_expr)))
            done = Status(sender=0, seq=2**53, tick=10**6, time_s=0.0, state="done", total_ticks=1).to_bytes()
            pub = sessions["outward"].declare_publisher(k.status)
            deadline = time.monotonic() + 10
            while not (heard["loopback"] and len(heard["logger loopback"]) >= 20) and time.monotonic() < deadline:
                pub.put(done)  # the run's end, forged: from here it reaches no one
                time.sleep(0.05)
            assert launch.sim_time() < 119.0, "the run was over before the forgeries"
        finally:
            for sess in sessions.values():
                sess.close()
        res = launch.wait(timeout_s=240)
    assert heard["loopback"], "over loopback the world's login hears the commands"
    assert heard["outward"] == []
    assert heard["logger loopback"], "over loopback the logger's login hears the world"
    assert heard["logger outward"] == []
    assert res.exit_code == 0, res.summary.get("events")
    assert res.summary["ticks"] == 2400
    assert res.summary["end_reason"] == "duration_reached"
