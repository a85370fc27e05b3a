"""Attacks on a live run, by a rogue Zenoh client on the run's own endpoint.

Two walls: the run's router (the world) refuses whoever has no credentials,
and what a role's credentials do not allow; every receiver refuses what could
not be true. Each test checks the run's outcome: no process dies, a lockstep
run keeps the digest of a clean run with the same seed, and what the
receivers refused is counted by reason.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgpack
import pytest
import zenoh

from formation_swarm.launch.launcher import Launch, RunResult, free_port
from formation_swarm.protocol import trust
from formation_swarm.protocol.batch import pack_batch
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import WORLD_ID, Command, FormationCode, Observation, Status, Telemetry, Truth
from formation_swarm.protocol.session import make_config
from tests.helpers import ROOT

pytestmark = pytest.mark.slow

FIG11 = "fig11_obstacles"
HUGE_SEQ = 2**53  # newer than anything real
FAR_TICK = 2**53
LINE = 1  # fig11's formation codes: triangle 0, line 1


def beyond_seq(msg: Command) -> bytes:
    """``msg`` on the wire with a seq one past what any decoder takes: our
    encoder refuses to write it, an attacker need not."""
    values = msgpack.unpackb(msg.to_bytes())
    values[3] = HUGE_SEQ + 1
    return msgpack.packb(values, use_bin_type=True)


def rogue(launch: Launch, user: str | None) -> zenoh.Session:
    """A client on the run's endpoint, with a role's credentials (or none)."""
    settings = launch.login(user) if user else None  # the files are gone once read: the launcher's copy
    return zenoh.open(make_config("client", [launch.endpoint], connect_timeout_s=3.0, settings=settings))


def put_all(sess: zenoh.Session, messages: list[tuple[str, bytes]], rounds: int, witness: str | None = None) -> None:
    """Each (key, payload) ``rounds`` times, with the publishers declared first
    (a put made before the router knows of them may be lost: that would hide a
    hole, not show a wall). A key nobody subscribes to in the run (the truth
    without a logger) never matches: with ``witness`` (a liveliness token the
    login may query) the wait ends once a query sent after the declarations is
    answered, as the router answers on the session's one link in order (no QoS
    lanes): every publisher that can match has by then."""
    pubs = {key: sess.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK) for key, _ in messages}
    if witness is not None:
        replies = list(sess.liveliness().get(witness, timeout=10.0))
        assert replies, f"no answer for {witness}"
    deadline = time.monotonic() + (0.0 if witness is not None else 10.0)
    while not all(p.matching_status.matching for p in pubs.values()) and time.monotonic() < deadline:
        time.sleep(0.01)
    for _ in range(rounds):
        for key, payload in messages:
            pubs[key].put(payload)


def attacks(k: Keys, tick: int) -> list[tuple[str, bytes]]:
    """What the issue's attacker did: absurd and plausible commands for robot 3,
    the leader's "done", codes stamped 2**53, fake observations, a fake end of
    run, fake truth and telemetry far in the future."""
    fake_reading = ((1, 0.9, 0.0, 0.0),)  # the leader "0.9 m ahead"
    return [
        (
            k.cmd(3),
            Command(
                sender=3, seq=HUGE_SEQ, tick=tick, left_mps=1e308, right_mps=1e308, formation=0, done=False
            ).to_bytes(),
        ),
        (
            k.cmd(3),
            beyond_seq(
                Command(sender=3, seq=HUGE_SEQ, tick=tick, left_mps=1.0, right_mps=2.0, formation=0, done=False)
            ),
        ),
        (
            k.cmd(1),
            Command(sender=1, seq=HUGE_SEQ, tick=tick, left_mps=1.5, right_mps=1.5, formation=0, done=True).to_bytes(),
        ),
        (k.codes, FormationCode(sender=1, seq=HUGE_SEQ, tick=FAR_TICK, code=LINE).to_bytes()),
        (
            k.obs(2),
            Observation(
                sender=WORLD_ID,
                seq=HUGE_SEQ,
                tick=tick + 1,
                time_s=0.0,
                pose=(0.0, 0.0, 0.0),
                readings=fake_reading,
                obstacles=(),
            ).to_bytes(),
        ),
        (
            k.obs(3),
            Observation(
                sender=WORLD_ID,
                seq=HUGE_SEQ,
                tick=tick + 1,
                time_s=0.0,
                pose=(0.0, 0.0, 0.0),
                readings=((2, 1e200, 0.0, 0.0),),
                obstacles=(),
            ).to_bytes(),
        ),
        (k.status, Status(sender=0, seq=HUGE_SEQ, tick=tick, time_s=0.0, state="done", total_ticks=1).to_bytes()),
        (
            k.truth,
            pack_batch(
                [
                    Truth(
                        sender=0,
                        seq=HUGE_SEQ,
                        tick=FAR_TICK,
                        time_s=0.0,
                        robots=((1, 0.0, 0.0, 0.0, True),),
                        targets=(),
                    ).to_bytes()
                ]
            ),
        ),
        (k.telemetry(2), pack_batch([_telemetry(FAR_TICK)])),
    ]


def _telemetry(tick: int) -> bytes:
    return Telemetry(
        sender=2,
        seq=HUGE_SEQ,
        tick=tick,
        time_s=0.0,
        reference=1,
        formation=0,
        measured=None,
        estimate=None,
        target_cov=None,
        rho_m=None,
        alpha_rad=None,
        vn=None,
        left_mps=0.0,
        right_mps=0.0,
        steering_to=0,
        changing=False,
        obs_dropped=0,
        formation_dropped=0,
        rejected=0,
    ).to_bytes()


def run_under_attack(swarm_launch: Callable[..., Launch], user: str | None, mode: str, **kwargs: Any) -> RunResult:
    launch = swarm_launch(FIG11, mode=mode, **kwargs)
    with rogue(launch, user) as sess:  # connected first: the attack lands while a short lockstep run goes on
        assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
        k = Keys(launch.run_id)
        put_all(sess, attacks(k, tick=int(launch.sim_time() / 0.05) + 1), rounds=20, witness=k.alive("world", 0))
        return launch.wait(timeout_s=240)


def assert_unharmed(res: RunResult) -> None:
    s = res.summary
    assert res.exit_code == 0, s.get("events")
    assert s["deaths"] == []
    assert all(p["exit_code"] == 0 for p in s["processes"].values()), s["processes"]
    changes = sorted((e["robot"], e["formation"]) for e in s["formation_events"])
    assert changes == sorted((r, f) for r in (1, 2, 3) for f in ("line", "triangle")), changes


def test_a_client_without_credentials_is_refused_by_the_router(swarm_launch: Callable[..., Launch]) -> None:
    launch = swarm_launch(FIG11, logger=False)
    assert launch.wait_until(lambda: launch.sim_time() >= 0.0, timeout_s=60)
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        rogue(launch, None)
    wrong = {"transport/auth/usrpwd": {"user": "agent-3", "password": "a-password-that-is-not-it"}}
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        zenoh.open(make_config("client", [launch.endpoint], connect_timeout_s=3.0, settings=wrong))
    res = launch.wait(timeout_s=240)
    assert res.exit_code == 0
    assert not (launch.run_dir / "secrets").exists()  # the run's passwords are gone with it


def test_the_loggers_credentials_cannot_drive_end_or_fake_anything(
    swarm_launch: Callable[..., Launch], clean_digest: str
) -> None:
    """The logger's login may only listen: every attack is refused at the router,
    so no receiver even sees one, and the lockstep run is bit-identical."""
    res = run_under_attack(swarm_launch, "logger", "lockstep", logger=False)
    assert_unharmed(res)
    s = res.summary
    assert s["ticks"] == 1061
    assert s["end_reason"] == "leader_finished"
    assert s["trajectory_digest"] == clean_digest
    assert s["rejected_total"] == 0, s["rejected"]  # nothing got through to be rejected


def test_the_loggers_credentials_in_real_time(swarm_launch: Callable[..., Launch]) -> None:
    res = run_under_attack(swarm_launch, "logger", "realtime", logger=False, overrides={"run.duration_s": 6.0})
    s = res.summary
    assert res.exit_code == 0
    assert s["deaths"] == []
    assert s["end_reason"] == "duration_reached"
    assert s["ticks"] == 120
    assert s["rejected_total"] == 0, s["rejected"]


def test_a_robots_own_credentials_cannot_send_what_could_not_be_true(
    swarm_launch: Callable[..., Launch], clean_digest: str
) -> None:
    """Agent 3's login may put robot 3's commands: an absurd one, or one for a
    tick to come, is refused by the world and counted; the run is unchanged."""
    launch = swarm_launch(FIG11, logger=False)
    k = Keys(launch.run_id)
    with rogue(launch, "agent-3") as sess:  # connected first: 1,061 ticks take about a second
        assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
        tick = int(launch.sim_time() / 0.05)
        put_all(
            sess,
            [
                (
                    k.cmd(3),
                    Command(
                        sender=3, seq=HUGE_SEQ, tick=tick, left_mps=1e308, right_mps=-1e308, formation=0, done=False
                    ).to_bytes(),
                ),
                (
                    k.cmd(3),
                    Command(
                        sender=3, seq=HUGE_SEQ, tick=FAR_TICK, left_mps=1.0, right_mps=1.0, formation=0, done=False
                    ).to_bytes(),
                ),
                (
                    k.cmd(3),
                    Command(
                        sender=3, seq=HUGE_SEQ, tick=tick, left_mps=1.0, right_mps=1.0, formation=200, done=False
                    ).to_bytes(),
                ),
            ],
            rounds=5,
        )
        res = launch.wait(timeout_s=240)
    assert_unharmed(res)
    s = res.summary
    assert s["trajectory_digest"] == clean_digest
    assert s["rejected"]["world"] == {
        "wheel speed out of bounds": 5,
        "tick ahead of the world": 5,
        "unknown formation": 5,
    }


def test_without_the_router_the_receivers_still_refuse_what_could_not_be_true(
    swarm_launch: Callable[..., Launch], clean_digest: str
) -> None:
    """With authentication off (anyone may connect), the receivers' checks
    alone: absurd values, replays and far-future ticks are counted, none is
    taken, and the lockstep run stays bit-identical. (Plausible forgeries need
    the router's wall: that is what the tests above show.)"""
    launch = swarm_launch(FIG11, auth=False)
    k = Keys(launch.run_id)
    with rogue(launch, None) as sess:  # connected first: 1,061 ticks take about a second
        assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
        tick = int(launch.sim_time() / 0.05)
        put_all(
            sess,
            [
                (
                    k.cmd(3),
                    Command(
                        sender=3, seq=HUGE_SEQ, tick=tick, left_mps=1e308, right_mps=1e308, formation=0, done=False
                    ).to_bytes(),
                ),
                (
                    k.cmd(2),
                    Command(
                        sender=2, seq=HUGE_SEQ, tick=FAR_TICK, left_mps=1.0, right_mps=1.0, formation=0, done=False
                    ).to_bytes(),
                ),
                (
                    k.codes,
                    FormationCode(sender=1, seq=HUGE_SEQ, tick=FAR_TICK, code=LINE).to_bytes(),
                ),  # to every follower
                (
                    k.obs(3),
                    Observation(
                        sender=WORLD_ID,
                        seq=HUGE_SEQ,
                        tick=0,
                        time_s=0.0,
                        pose=(0.0, 0.0, 0.0),
                        readings=(),
                        obstacles=(),
                    ).to_bytes(),
                ),  # a replay of tick 0
                (
                    k.obs(2),
                    Observation(
                        sender=WORLD_ID,
                        seq=HUGE_SEQ,
                        tick=FAR_TICK,
                        time_s=0.0,
                        pose=(0.0, 0.0, 0.0),
                        readings=((1, 1e200, 0, 0),),
                        obstacles=(),
                    ).to_bytes(),
                ),
                (
                    k.truth,
                    pack_batch(
                        [
                            Truth(
                                sender=0,
                                seq=HUGE_SEQ,
                                tick=FAR_TICK,
                                time_s=0.0,
                                robots=((1, 0.0, 0.0, 0.0, True),),
                                targets=(),
                            ).to_bytes()
                        ]
                    ),
                ),
                (k.telemetry(2), pack_batch([_telemetry(FAR_TICK)])),
            ],
            rounds=4,
        )
        res = launch.wait(timeout_s=240)
    assert_unharmed(res)
    s = res.summary
    assert s["trajectory_digest"] == clean_digest
    rejected = s["rejected"]
    assert rejected["world"] == {"wheel speed out of bounds": 4, "tick ahead of the world": 4}
    # agent 2's inbox (robot/2/*) also hears the forged cmd and telemetry of robot 2: not its to take
    assert rejected["agent-2"] == {"tick ahead of the world": 4, "reading out of bounds": 4, "unexpected key": 8}
    # and robot 3's forged cmd; the forged code reached every follower, and the leader, whose inbox matches it too
    assert rejected["agent-3"] == {"tick ahead of the world": 4, "replayed or reordered": 4, "unexpected key": 4}
    assert rejected["agent-1"] == {"unexpected key": 4}
    assert rejected["logger"] == {"tick past the run's end": 8}
    assert s["parts"]["logger"]["messages"]["truth"] == 1061  # the fake one never entered the recording


def test_a_second_agent_for_a_flying_robot_is_refused(swarm_launch: Callable[..., Launch], tmp_path: Path) -> None:
    launch = swarm_launch(
        FIG11, logger=False, overrides={"run.duration_s": 600.0, "leader.waypoints": [[0.0, 0.0], [0.0, 1000.0]]}
    )
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    argv = [
        sys.executable,
        "-m",
        "formation_swarm.nodes.agent.main",
        "--id",
        "2",
        "--scenario",
        str(launch.run_dir / "scenario.toml"),
        "--run",
        launch.run_id,
        "--connect",
        launch.endpoint,
        "--auth",
        str(trust.write_settings(tmp_path / "agent-2.json", launch.login("agent-2") or {})),
        "--peers-timeout",
        "20",
    ]
    try:
        second = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
        assert second.returncode == 4, second.stderr
        assert "robot 2 already has an agent in run" in second.stderr
        assert "Traceback" not in second.stderr
        assert launch.sim_time() > 1.0
        assert launch.children["agent-2"].poll() is None
    finally:
        launch.stop(graceful_first=False)


def test_a_second_world_for_a_running_run_is_refused(swarm_launch: Callable[..., Launch], tmp_path: Path) -> None:
    """Started twice (by hand, or by a service manager), a world joined the run and
    stepped phantom robots to its end, saying exit 0. It now refuses, as a second
    agent does, and writes neither stats nor a summary over the first one's."""
    launch = swarm_launch(
        FIG11,
        logger=False,
        auth=False,
        overrides={"run.duration_s": 600.0, "leader.waypoints": [[0.0, 0.0], [0.0, 1000.0]]},
    )
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    argv = [
        sys.executable,
        "-m",
        "formation_swarm.nodes.world.main",
        "--scenario",
        str(launch.run_dir / "scenario.toml"),
        "--run",
        launch.run_id,
        "--zenoh-mode",
        "client",
        "--connect",
        launch.endpoint,
        "--mode",
        "realtime",
        "--stats",
        str(tmp_path / "second.json"),
        "--out",
        str(tmp_path / "second"),
        "--peers-timeout",
        "20",
    ]
    try:
        second = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
        assert second.returncode == 4, second.stderr
        assert f"run {launch.run_id!r} already has a world" in second.stderr
        assert "two worlds would both step its robots: not starting" in second.stderr
        assert "Traceback" not in second.stderr
        assert not (tmp_path / "second.json").exists()
        assert not (tmp_path / "second" / "summary.json").exists()
        at = launch.sim_time()
        assert launch.wait_until(lambda: launch.sim_time() > at, timeout_s=30)  # the run goes on
        assert launch.children["world"].poll() is None
    finally:
        launch.stop(graceful_first=False)


def test_the_deploy_router_refuses_strangers_and_keeps_each_role_to_its_keys(tmp_path: Path) -> None:
    """deploy/router.json5 with the rules of swarm secure, as deploy/README.md
    starts it: no login, no connection; a robot's login drives that robot only."""
    run = "deploy-check"
    secure = tmp_path / "secure"
    made = subprocess.run(
        [sys.executable, "-m", "formation_swarm.cli", "secure", FIG11, "--run", run, "--out", str(secure)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert made.returncode == 0, made.stderr
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    config = ROOT / "deploy" / "router.json5"
    router = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "formation_swarm.nodes.router",
            "--config",
            str(config),
            "--listen",
            endpoint,
            "--auth",
            str(secure / "router.json"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert router.stdout is not None
        assert "listening on" in router.stdout.readline()

        def client(user: str | None) -> zenoh.Session:
            settings = trust.read_settings(secure / f"{user}.json") if user else None
            return zenoh.open(make_config("client", [endpoint], connect_timeout_s=3.0, settings=settings))

        with pytest.raises(zenoh.ZError, match="Unable to connect"):
            client(None)
        k = Keys(run)
        got: list[str] = []
        with client("world") as world, client("agent-2") as agent:
            world.declare_subscriber(k.all_cmd, lambda s: got.append(str(s.key_expr)))
            put_all(agent, [(k.cmd(3), b"forged"), (k.cmd(2), b"own")], rounds=1)
            deadline = time.monotonic() + 10
            while got != [k.cmd(2)] and time.monotonic() < deadline:  # the refused ones were sent first
                time.sleep(0.01)
        assert got == [k.cmd(2)]
    finally:
        router.terminate()
        router.wait(timeout=10)


def test_a_world_that_dies_takes_no_one_with_it_silently(swarm_launch: Callable[..., Launch]) -> None:
    """The world (the run's router) is killed: the logger closes its recording
    and every agent leaves on its own, and swarm run fails, saying why."""
    launch = swarm_launch(FIG11, mode="realtime", overrides={"run.duration_s": 30.0})
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    os.kill(launch.pids()["world"], signal.SIGKILL)
    res = launch.wait(timeout_s=60)
    assert res.exit_code == 1
    assert res.summary["end_reason"] == "role_failed"
    for name in ("logger", "agent-1", "agent-2", "agent-3"):
        child = launch.children[name]
        assert child.proc is not None
        assert child.proc.returncode == 0, name
        assert child.stop_sent_at is None, f"{name} had to be stopped"  # it left by itself
    assert "ended (the world left)" in (launch.run_dir / "logs" / "logger.log").read_text()
    assert res.recording.stat().st_size > 1000


def test_a_run_that_loses_every_follower_fails(swarm_run: Callable[..., RunResult]) -> None:
    res = swarm_run(FIG11, logger=False, kills=["agent-2@5", "agent-3@5"])
    assert res.exit_code == 1
    assert sorted(d["robot"] for d in res.summary["deaths"]) == [2, 3]
    assert res.summary["failure"] == "every follower (2, 3) lost its agent"


def test_after_a_freeze_an_agent_answers_only_the_newest_observation(swarm_launch: Callable[..., Launch]) -> None:
    launch = swarm_launch(FIG11, mode="realtime", logger=False, overrides={"run.duration_s": 6.0})
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    pid = launch.pids()["agent-2"]
    os.kill(pid, signal.SIGSTOP)
    try:
        frozen_at = launch.sim_time()
        assert launch.wait_until(lambda: launch.sim_time() >= frozen_at + 1.5, timeout_s=30)  # 30 ticks go by
    finally:
        os.kill(pid, signal.SIGCONT)
    res = launch.wait(timeout_s=60)
    agent = res.summary["parts"]["agent-2"]
    assert agent["superseded"] >= 20  # the stale ones were skipped, not answered late
    assert agent["answered"] + agent["superseded"] <= res.summary["ticks"]
    assert res.summary["deaths"] == []


def test_the_deploy_router_without_rules_forwards_nothing() -> None:
    """deploy/router.json5 started without --auth: it runs, but denies every message."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    config = ROOT / "deploy" / "router.json5"
    argv = [sys.executable, "-m", "formation_swarm.nodes.router", "--config", str(config), "--listen", endpoint]
    router = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert router.stdout is not None
        assert "listening on" in router.stdout.readline()
        said = router.stdout.readline()  # what it enforces is the file's, until --auth gives a run's rules
        assert "no --auth: the access rules, logins and TLS are" in said, said
        assert "denies everything until --auth gives a run's rules" in said
        k = Keys("open-check")
        got: list[str] = []
        conf = make_config("client", [endpoint], connect_timeout_s=3.0)
        with zenoh.open(conf) as listener, zenoh.open(conf) as talker:
            listener.declare_subscriber(k.everything, lambda s: got.append(str(s.key_expr)))
            pub = talker.declare_publisher(k.cmd(1))
            pub.put(b"x")
            time.sleep(0.5)  # nothing must arrive: a wait for an absence has no condition to wait on
            assert not pub.matching_status.matching  # the router told it of no subscriber
        assert got == []
    finally:
        router.terminate()
        router.wait(timeout=10)


def test_a_router_without_auth_says_that_anyone_who_reaches_it_can_join() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    argv = [sys.executable, "-m", "formation_swarm.nodes.router", "--listen", endpoint]
    router = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert router.stdout is not None
        assert router.stdout.readline().startswith(f"router: listening on {endpoint}")
        said = router.stdout.readline()
        assert said.startswith(
            "router: no --auth: no logins and no access rules; anyone who reaches this port can "
            "join any run through it and drive its robots"
        ), said
    finally:
        router.terminate()
        router.wait(timeout=10)
