"""Processes the run does not start: an outside agent flies a robot, an
observer watches the whole run.

``swarm run S --external 3`` starts everything but robot 3's agent and
prints the one command line that starts it; the follower written from
docs/protocol.md alone (tests/helpers/foreign_follower.py) takes that line's
values and its login, and the run completes as with our agent, in lockstep
and in real time; started before the router exists, it retries until it is
there. The observer login hears every key of a run and can send nothing:
the router drops what it puts.
"""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import msgpack
import pytest
import zenoh

from formation_swarm.launch.launcher import Launch, RunResult, free_port
from formation_swarm.launch.plan import Plan, RunOptions
from formation_swarm.protocol import acl, trust
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import WORLD_ID, Command, FormationCode, Observation, Status
from formation_swarm.protocol.session import make_config
from tests.helpers import Console
from tests.helpers import foreign_follower as foreign

FOREIGN = Path(foreign.__file__)
FIG11 = "fig11_obstacles"
HUGE_SEQ = 2**53


# -- the plan: what an external robot changes, before anything starts -------------------


def test_an_external_robot_gets_no_agent_and_every_role_the_peers_timeout(tmp_path: Path) -> None:
    plan = Plan.make(FIG11, RunOptions(external=[3], out=tmp_path / "run", peers_timeout_s=90.0))
    assert plan.external == (3,)
    lines = plan.command_lines("tcp/127.0.0.1:9", {}, remote_agents=False, live=None)
    assert sorted(lines) == ["agent-1", "agent-2", "logger", "world"]
    for argv in lines.values():
        assert argv[argv.index("--peers-timeout") + 1] == "90"
    assert plan.names() == ["world", "logger", "agent-1", "agent-2"]


@pytest.mark.parametrize(
    ("options", "said"),
    [
        ({"external": [4]}, "external: 4 is not a robot of fig11-obstacles; its robots are 1, 2, 3"),
        ({"external": [3, 3]}, "external: robot 3 is named twice"),
        (
            {"external": [3], "faults": ["kill agent-3@5s"]},
            "cannot execute a process fault on agent-3: it is external",
        ),
        ({"observer_login": "o.json", "auth": False}, "a run without logins (auth=False) has none to give"),
        ({"peers_timeout_s": 0}, "peers_timeout_s: a number of seconds in (0, 1e6]"),
    ],
)
def test_what_cannot_be_left_outside_is_refused_before_anything_starts(
    tmp_path: Path, options: dict[str, Any], said: str
) -> None:
    with pytest.raises(ValueError, match=re.escape(said)):
        Launch(FIG11, out=tmp_path / "run", progress=lambda _l: None, **options)
    assert not (tmp_path / "run").exists()


def test_the_swarm_run_flags_reach_the_launch(tmp_path: Path) -> None:
    bad = subprocess.run(
        [sys.executable, "-m", "formation_swarm.cli", "run", FIG11, "--external", "9", "--out", str(tmp_path / "r")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert bad.returncode == 2
    assert "external: 9 is not a robot of fig11-obstacles" in bad.stderr


# -- an outside agent flies robot 3 ---------------------------------------------------------


def _start_foreign(flags: list[str], stats: Path, log: Path) -> subprocess.Popen[bytes]:
    with open(log, "wb") as out:
        return subprocess.Popen(
            [sys.executable, str(FOREIGN), *flags, "--stats", str(stats)],
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        )


def _reap(proc: subprocess.Popen[bytes], timeout_s: float) -> int:
    try:
        return proc.wait(timeout=timeout_s)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _check_flown(summary: dict[str, Any], theirs: dict[str, Any]) -> None:
    """Robot 3 flown by the outside agent to the run's end, reported as any robot."""
    assert summary["exit_code"] == 0, summary["events"]
    assert summary["external_robots"] == [3]
    assert "agent-3" not in summary["processes"]
    r3 = summary["followers"]["3"]
    assert r3["external"] is True
    assert r3["rms_m"] < 1.2  # the foreign pursuit law: ~0.7 m on fig11 (test_foreign_follower.py)
    assert summary["deaths"] == []
    assert summary["rejected_total"] == 0, summary["rejected"]
    assert summary["parts"]["world"]["duplicate_agents"] == {}
    assert theirs["exit"] == "done"
    assert theirs["rejected"] == {}
    assert theirs["done_tick"] == summary["ticks"]


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_swarm_run_leaves_robot_3_to_the_agent_its_one_line_starts(tmp_path: Path, mode: str) -> None:
    out = tmp_path / "run"
    argv = [sys.executable, "-m", "formation_swarm.cli", "run", FIG11, "--external", "3", "--out", str(out)]
    if mode == "realtime":  # 20 s of the wall clock, not 53
        argv += ["--mode", "realtime", "--set", "run.duration_s=20"]
    run = Console(argv, "swarm agent --id 3")
    foreign_proc = None
    try:
        assert run.seen.wait(timeout=60), run.text
        line = next(ln for ln in run.lines if "swarm agent --id 3" in ln)
        words = shlex.split(line)
        flags = words[words.index("agent") + 1 :]
        assert flags[::2] == ["--id", "--scenario", "--run", "--connect", "--auth"]
        assert Path(flags[flags.index("--auth") + 1]) == out / "secrets" / "agent-3.json"
        foreign_proc = _start_foreign(flags, tmp_path / "foreign.json", tmp_path / "foreign.log")
        assert run.wait(timeout_s=300) == 0, run.text
        assert _reap(foreign_proc, 30) == 0, (tmp_path / "foreign.log").read_text()
    finally:
        run.close()
        if foreign_proc is not None and foreign_proc.poll() is None:
            foreign_proc.kill()
            foreign_proc.wait()
    summary = json.loads((out / "summary.json").read_text())
    theirs = json.loads((tmp_path / "foreign.json").read_text())
    _check_flown(summary, theirs)
    assert summary["mode"] == mode
    if mode == "lockstep":
        assert summary["end_reason"] == "leader_finished"
        assert summary["lockstep_misses"] == 0
        assert theirs["answered"] == summary["ticks"]
    else:
        assert summary["end_reason"] == "duration_reached"
        assert summary["ticks"] == 400
    assert not (out / "secrets").exists()  # its login went with the run


@pytest.mark.slow
def test_an_outside_agent_started_before_the_router_retries_until_it_is_there(tmp_path: Path) -> None:
    """Started 5 s before the world listens, the outside agent connects once it
    does (the connect timeout and retry of docs/protocol.md) and flies the run."""
    launch = Launch(FIG11, external=[3], out=tmp_path / "run", progress=lambda _l: None)
    agent = launch.prepare()[3]  # its endpoint, run id, login and scenario, before the router exists
    assert agent.login == tmp_path / "run" / "secrets" / "agent-3.json"
    assert agent.endpoint == launch.endpoint
    foreign_proc = _start_foreign(agent.flags(), tmp_path / "foreign.json", tmp_path / "foreign.log")
    try:
        # The point of the test: nothing listens for these 5 s, and the agent is still trying.
        started = time.monotonic()
        while time.monotonic() - started < 5.0:
            assert foreign_proc.poll() is None, (tmp_path / "foreign.log").read_text()
            time.sleep(0.1)
        launch.start()
        res = launch.wait(timeout_s=240)
        assert _reap(foreign_proc, 30) == 0, (tmp_path / "foreign.log").read_text()
    finally:
        launch.stop()
        if foreign_proc.poll() is None:
            foreign_proc.kill()
            foreign_proc.wait()
    theirs = json.loads((tmp_path / "foreign.json").read_text())
    _check_flown(res.summary, theirs)
    assert res.summary["lockstep_misses"] == 0
    assert theirs["answered"] == res.summary["ticks"]


@pytest.mark.slow
def test_the_fixture_keyword_and_join(swarm_run: Callable[..., RunResult], tmp_path: Path) -> None:
    def join(launch: Launch) -> subprocess.Popen[bytes]:
        return _start_foreign(launch.external[3].flags(), tmp_path / "foreign.json", tmp_path / "foreign.log")

    res = swarm_run(FIG11, external=[3], join=join, logger=False)
    _check_flown(res.summary, json.loads((tmp_path / "foreign.json").read_text()))


# -- the observer ---------------------------------------------------------------------------


class Heard:
    """Everything a session hears on the run's keys and tokens: key kinds and payloads."""

    def __init__(self, session: zenoh.Session, keys: Keys) -> None:
        self.kinds: set[str] = set()
        self.payloads: set[bytes] = set()
        self.lock = threading.Lock()
        self.prefix = keys.prefix
        session.declare_subscriber(keys.everything, self._data)
        session.liveliness().declare_subscriber(keys.alive_any, self._token, history=True)

    def _data(self, sample: zenoh.Sample) -> None:
        rest = str(sample.key_expr)[len(self.prefix) + 1 :].split("/")
        with self.lock:
            self.kinds.add(rest[-1])  # obs, cmd, formation, telemetry, truth, status
            self.payloads.add(sample.payload.to_bytes())

    def _token(self, sample: zenoh.Sample) -> None:
        with self.lock:
            self.kinds.add("alive/" + str(sample.key_expr).split("/alive/", 1)[1].split("/")[0])


def _forgeries(k: Keys, tick: int) -> list[tuple[str, bytes]]:
    """What would change the run if it got through: a command robot 3's world
    would take, the leader's "done", a code, an observation, the end of the run."""
    return [
        (
            k.cmd(3),
            Command(sender=3, seq=HUGE_SEQ, tick=tick, left_mps=1.0, right_mps=2.0, formation=0, done=False).to_bytes(),
        ),
        (
            k.cmd(1),
            Command(sender=1, seq=HUGE_SEQ, tick=tick, left_mps=0.0, right_mps=0.0, formation=0, done=True).to_bytes(),
        ),
        (k.codes, FormationCode(sender=1, seq=HUGE_SEQ, tick=tick, code=1).to_bytes()),
        (
            k.obs(2),
            Observation(
                sender=WORLD_ID,
                seq=HUGE_SEQ,
                tick=tick + 1,
                time_s=0.0,
                pose=(0.0, 0.0, 0.0),
                readings=(),
                obstacles=(),
            ).to_bytes(),
        ),
        (k.status, Status(sender=0, seq=HUGE_SEQ, tick=tick, time_s=0.0, state="done", total_ticks=1).to_bytes()),
        (f"{k.prefix}/observer/marker", b"observer was here"),
    ]


@pytest.fixture
def observed(tmp_path: Path) -> Iterator[tuple[Launch, Path]]:
    launch = Launch(FIG11, out=tmp_path / "run", observer_login=tmp_path / "observer.json", progress=lambda _l: None)
    with launch:
        launch.prepare()
        yield launch, tmp_path / "observer.json"


@pytest.mark.slow
def test_the_observer_hears_every_key_of_a_run_and_its_puts_go_nowhere(
    observed: tuple[Launch, Path], clean_digest: str
) -> None:
    """A leaked observer login at worst: it hears everything, and its forgeries
    reach no receiver; the run is bit-identical to a clean one."""
    launch, login = observed
    settings = trust.read_settings(login)
    assert trust.login_user(settings) == acl.OBSERVER
    k = Keys(launch.run_id)
    launch.start()  # the router exists from here on; the observers are not waited for
    conf = make_config("client", [launch.endpoint], connect_timeout_s=30.0, settings=settings)
    with zenoh.open(conf) as listener, zenoh.open(conf) as rogue:
        heard = Heard(listener, k)
        assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=90)
        forged = _forgeries(k, tick=int(launch.sim_time() / 0.05) + 1)
        pubs = [(rogue.declare_publisher(key), payload) for key, payload in forged]
        # Each has a subscriber in the run (the marker: the listener's), so its puts leave the client.
        deadline = time.monotonic() + 10.0
        while not all(p.matching_status.matching for p, _ in pubs) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert all(p.matching_status.matching for p, _ in pubs)
        for _ in range(10):
            for pub, payload in pubs:
                pub.put(payload)
        # A query answered after the puts on the same link: the router has read them all.
        assert list(rogue.liveliness().get(k.alive("world", 0), timeout=10.0))
        res = launch.wait(timeout_s=240)
    with heard.lock:
        kinds, payloads = set(heard.kinds), set(heard.payloads)
    assert {"obs", "cmd", "formation", "telemetry", "truth", "status"} <= kinds, kinds
    assert {"alive/world", "alive/agent", "alive/logger", "alive/launcher"} <= kinds, kinds
    assert payloads.isdisjoint(payload for _, payload in forged)  # no subscriber of the run got one
    s = res.summary
    assert res.exit_code == 0, s["events"]
    assert s["end_reason"] == "leader_finished"
    assert s["ticks"] == 1061
    assert s["trajectory_digest"] == clean_digest
    assert s["rejected_total"] == 0, s["rejected"]  # nothing reached a receiver to be refused
    world = s["parts"]["world"]
    assert world["messages"]["cmd_received"] == 3 * s["ticks"]  # one answer per robot and tick: none forged
    assert world["duplicate_agents"] == {}
    assert [(e["robot"], e["formation"]) for e in s["formation_events"] if e["robot"] == 1] == [
        (1, "line"),
        (1, "triangle"),
    ]


def test_swarm_secure_writes_the_observer_login_on_request(tmp_path: Path) -> None:
    out = tmp_path / "secure"
    made = subprocess.run(
        [sys.executable, "-m", "formation_swarm.cli", "secure", FIG11, "--run", "r1", "--out", str(out), "--observer"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert made.returncode == 0, made.stderr
    assert f"observer: --connect tcp/ROUTER:7447 --auth {out / 'observer.json'}" in made.stdout
    assert trust.login_user(trust.read_settings(out / "observer.json")) == acl.OBSERVER
    access = json.loads((out / "router.json").read_text())["access_control"]
    policy = next(p for p in access["policies"] if p["id"] == acl.OBSERVER)
    rules = {r["id"]: r for r in access["rules"]}
    assert policy["rules"] == [
        "learn-subscribers",
        "observer-sub",
        "observer-data",
        "observer-withheld",
        "observer-watch",
        "observer-seen",
    ]
    assert all(rules[r]["flows"] == ["egress"] or "put" not in rules[r]["messages"] for r in policy["rules"])


# -- what a client sees of a subscription wider than its grant -------------------------------


def test_a_subscription_wider_than_the_grant_is_silently_empty(tmp_path: Path) -> None:
    """Declared without an error, refused by the router: nothing arrives on it,
    unless the session's own allowed subscription brings a message in."""
    run = f"wide-{uuid.uuid4().hex[:8]}"
    k = Keys(run)
    files = trust.write_run_secrets(tmp_path / "secrets", run, (1, 2, 3), leader_id=1)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router_conf = make_config("router", listen=[endpoint], settings=trust.read_settings(files["router"]))
    login = trust.read_settings(files["agent-2"])
    with zenoh.open(router_conf) as world, zenoh.open(make_config("client", [endpoint], settings=login)) as agent:
        wide: list[str] = []
        agent.declare_subscriber(f"{k.prefix}/robot/**", lambda s: wide.append(str(s.key_expr)))  # no error
        obs = world.declare_publisher(k.obs(2))
        # A query answered after the declaration on the same link: the router has taken it (or refused it).
        assert list(agent.liveliness().get(k.alive("world", 0), timeout=2.0)) == []
        assert not obs.matching_status.matching  # refused: the world's put has no subscriber
        obs.put(b"x")
        assert list(agent.liveliness().get(k.alive("world", 0), timeout=2.0)) == []  # and after the put
        assert wide == []
        inbox: list[str] = []
        agent.declare_subscriber(k.inbox(2), lambda s: inbox.append(str(s.key_expr)))
        deadline = time.monotonic() + 5.0
        while not obs.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.01)
        obs.put(msgpack.packb([1]))
        deadline = time.monotonic() + 5.0
        while not (inbox and wide) and time.monotonic() < deadline:  # one callback after the other
            time.sleep(0.01)
        assert inbox == [k.obs(2)]
        assert wide == [k.obs(2)]  # in the session, both subscriptions match what came in


@pytest.mark.slow
def test_a_second_agent_of_a_robot_is_refused_by_the_world_and_counted(
    swarm_launch: Callable[..., Launch], tmp_path: Path
) -> None:
    """Zenoh merges the two agents' tokens, so the world tells the second one by
    its answers: one command per robot and tick is taken, the other counted."""
    launch = swarm_launch(FIG11, external=[3], logger=False)
    flags = launch.external[3].flags()
    first = _start_foreign(flags, tmp_path / "first.json", tmp_path / "first.log")
    second = None
    try:
        assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=90)
        # A copy of the login, taken before the launcher deleted it: the file is gone once the first connects.
        copy = trust.write_settings(tmp_path / "agent-3-copy.json", launch.login("agent-3"))
        second = _start_foreign(
            [*flags[:-1], str(copy), "--fly-beside"], tmp_path / "second.json", tmp_path / "second.log"
        )
        res = launch.wait(timeout_s=240)
        assert _reap(first, 30) == 0, (tmp_path / "first.log").read_text()
        assert _reap(second, 30) == 0, (tmp_path / "second.log").read_text()
    finally:
        for p in (first, second):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
    s, world = res.summary, res.summary["parts"]["world"]
    theirs = json.loads((tmp_path / "second.json").read_text())
    assert res.exit_code == 0, s["events"]
    assert s["deaths"] == []
    assert theirs["answered"] > 0  # it flew beside the first one: each of its answers a second one
    # Every answer beyond one per robot and tick is refused: a second one for the
    # tick (counted as such, or as a replay when its seq is lower), or a late one.
    duplicates = world["duplicate_agents"].get("3", 0)
    replays = s["rejected"].get("world", {}).get("replayed or reordered", 0)
    extra = world["messages"]["cmd_received"] - 3 * s["ticks"]
    assert duplicates + replays + world["late_answers"] == extra > 0, (duplicates, replays, world["late_answers"])
    assert s["lockstep_misses"] == 0
    assert world["duplicate_agents"].keys() <= {"3"}
