"""What a stolen login achieves at worst, one role at a time.

The router keeps each login to its role's keys (tests/system/test_attacks.py);
these tests give the thief a role's own login and do what that role may do,
plausibly: the run still completes all its ticks with the right end reason,
and the robots the login does not own fly as in a clean run (their own
trajectory digests, ``robot_digests``, are equal). And the logins themselves
do not stay on disk: each process deletes its own once read.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from formation_swarm.launch.launcher import Launch
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Command
from tests.system.test_attacks import FIG11, HUGE_SEQ, assert_unharmed, attacks, put_all, rogue

pytestmark = pytest.mark.slow

FORGED = 1000  # forged "done" commands, one per tick
# 2,400 ticks, 2-3 s of wall time in lockstep: long enough to be running still
# when a test acts (the launcher's view of the sim time lags up to 0.25 s).
LONG = {"run.duration_s": 120.0, "leader.waypoints": [[0.0, 0.0], [0.0, 1000.0]]}


def _clean(tmp: Path, **kwargs: Any) -> dict[str, Any]:
    with Launch(FIG11, out=tmp / "run", logger=False, progress=lambda _l: None, **kwargs) as run:
        res = run.wait(timeout_s=240)
    assert res.exit_code == 0
    return res.summary


@pytest.fixture(scope="module")
def clean(clean_run: dict[str, Any]) -> dict[str, Any]:
    """A clean lockstep fig11 run's summary (tests/system/conftest.py, shared with
    the attacks' tests): the digests a forgery must leave alone."""
    return clean_run


@pytest.fixture(scope="module")
def clean_long(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return _clean(tmp_path_factory.mktemp("clean-long"), overrides=LONG)


def _witnessed(sess: Any, key: str) -> None:
    """Wait until the router has taken what this session declared so far: a
    liveliness query sent after it is answered in order on the one link."""
    assert list(sess.liveliness().get(key, timeout=10.0)), f"no answer for {key}"


def test_a_leaked_leader_login_cannot_end_the_run(swarm_launch: Callable[..., Launch], clean: dict[str, Any]) -> None:
    """The leader's login says "done" for each of the next 1,000 ticks from about
    tick 40 of 1,061 (one of them lands on the tick the world is at). Before, the
    world took the leader's word: the run ended there, exit 0, "the leader
    reached its last waypoint". Now the world sees the leader 3 m along an 80 m
    path: each forgery is rejected whole, and the leader's own answers count."""
    launch = swarm_launch(FIG11, logger=False)
    assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
    first = int(round(launch.sim_time() / 0.05))
    k = Keys(launch.run_id)
    forged = [
        Command(sender=1, seq=HUGE_SEQ, tick=tick, left_mps=0.0, right_mps=0.0, formation=0, done=True).to_bytes()
        for tick in range(first, first + FORGED)
    ]
    with rogue(launch, "agent-1") as sess:
        put_all(sess, [(k.cmd(1), payload) for payload in forged], rounds=1)
        res = launch.wait(timeout_s=240)
    assert_unharmed(res)
    s = res.summary
    assert (s["ticks"], s["end_reason"], s["ended_at_s"]) == (1061, "leader_finished", clean["ended_at_s"])
    assert s["rejected"]["world"] == {"done before the last waypoint": FORGED}
    assert s["trajectory_digest"] == clean["trajectory_digest"]
    assert s["robot_digests"] == clean["robot_digests"]


def test_a_leaked_follower_login_holding_a_dead_agents_token_does_not_hide_its_death(
    swarm_launch: Callable[..., Launch], clean_long: dict[str, Any]
) -> None:
    """Agent 2's login holds robot 2's token, then the real agent 2 dies (SIGKILL,
    outside the schedule). Zenoh merges the two tokens, so the token alone would
    hide the death; the world hears agent 2's session close, sees nobody left
    to take robot 2's observations, and counts robot 2 lost at once
    (nodes.world.sessions): a death like any other, the second session
    reported, no tick waits its deadline; the leader flies as in a clean run."""
    launch = swarm_launch(FIG11, logger=False, overrides=LONG)
    assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
    k = Keys(launch.run_id)
    with rogue(launch, "agent-2") as sess:
        token = sess.liveliness().declare_token(k.alive("agent", 2))
        _witnessed(sess, k.alive("agent", 2))
        os.kill(launch.pids()["agent-2"], signal.SIGKILL)
        res = launch.wait(timeout_s=120)
        token.undeclare()
    s = res.summary
    assert (res.exit_code, s["ticks"], s["end_reason"]) == (0, 2400, "duration_reached")
    assert [(d["robot"], d["cause"]) for d in s["deaths"]] == [(2, "lost")]
    assert (s["lockstep_misses"], s["stalls"], s["not_reproducible"]) == (0, [], [])
    assert [e["robot"] for e in s["events"] if e["event"] == "robot login used twice"] == [2]
    assert s["robot_digests"]["1"] == clean_long["robot_digests"]["1"]
    assert s["rejected_total"] == 0


def test_a_leaked_logger_login_can_listen_and_hold_the_loggers_token_only(
    swarm_launch: Callable[..., Launch], clean: dict[str, Any]
) -> None:
    """The logger's login, beside the real logger: it holds the logger's token and
    tries every forgery of the attacks. The router lets none through; at the end
    the agents wait for a logger token that stays (bounded waits); the run
    completes, bit-identical."""
    launch = swarm_launch(FIG11)
    assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
    k = Keys(launch.run_id)
    with rogue(launch, "logger") as sess:
        token = sess.liveliness().declare_token(k.alive("logger", 0))
        tick = int(launch.sim_time() / 0.05) + 1
        put_all(sess, attacks(k, tick), rounds=5, witness=k.alive("world", 0))
        assert launch.children["world"].poll() is None  # the router took every put while the run went on
        res = launch.wait(timeout_s=240)
        token.undeclare()
    assert_unharmed(res)
    s = res.summary
    assert (s["ticks"], s["end_reason"]) == (1061, "leader_finished")
    assert s["trajectory_digest"] == clean["trajectory_digest"]
    assert s["rejected_total"] == 0
    assert s["parts"]["logger"]["messages"]["truth"] == 1061  # the real logger recorded every tick


def test_a_leaked_launcher_login_can_hear_the_status_and_hold_the_launchers_token_only(
    swarm_launch: Callable[..., Launch], clean_long: dict[str, Any]
) -> None:
    """The launcher's login, beside the real launcher: it hears the status and
    the world's fault calls, holds a second launcher token and tries every
    forgery of the attacks. The router lets none through; the run completes,
    bit-identical, and the real launcher still sees it end."""
    launch = swarm_launch(FIG11, logger=False, overrides=LONG)
    assert launch.wait_until(lambda: launch.sim_time() >= 0.0, timeout_s=60)
    k = Keys(launch.run_id)
    with rogue(launch, "launcher") as sess:
        heard: list[bytes] = []
        sess.declare_subscriber(k.status, lambda sample: heard.append(sample.payload.to_bytes()))
        token = sess.liveliness().declare_token(k.alive("launcher", 0))
        put_all(sess, attacks(k, tick=int(launch.sim_time() / 0.05) + 1), rounds=5, witness=k.alive("world", 0))
        assert launch.children["world"].poll() is None  # the router took every put while the run went on
        res = launch.wait(timeout_s=240)
        token.undeclare()
    s = res.summary
    assert res.exit_code == 0, s["failure"]
    assert all(p["exit_code"] == 0 for p in s["processes"].values()), s["processes"]
    assert (s["ticks"], s["end_reason"]) == (2400, "duration_reached")
    assert s["trajectory_digest"] == clean_long["trajectory_digest"]
    assert s["rejected_total"] == 0, s["rejected"]  # nothing got through to be rejected
    assert len(heard) >= 1  # what the login may do, it does


def test_a_local_run_has_no_world_login_to_steal(swarm_launch: Callable[..., Launch]) -> None:
    """The world of a local run is its router: it logs in as nobody."""
    launch = swarm_launch(FIG11, logger=False, overrides=LONG)
    assert launch.login("world") is None
    assert launch.login("agent-2") is not None
    assert launch.wait(timeout_s=120).exit_code == 0


def _files_holding(folder: Path, secrets: list[str]) -> list[str]:
    found = []
    for p in folder.rglob("*"):
        if p.is_file() and any(pw.encode() in p.read_bytes() for pw in secrets):
            found.append(str(p.relative_to(folder)))
    return sorted(found)


def test_no_password_stays_on_disk_and_a_restarted_agent_still_logs_in(swarm_launch: Callable[..., Launch]) -> None:
    """Before, secrets/ held every process's login and passwords.txt (every
    password of the run) for the whole local run. Now each process deletes its
    own once read; the launcher keeps them in memory and writes a fresh one for
    a restarted agent, which deletes it the same way."""
    launch = swarm_launch(FIG11, logger=False, faults=["restart agent-3@2s after=1"], overrides=LONG)
    logins = [launch.login(user) or {} for user in ("logger", "launcher", "agent-1", "agent-2", "agent-3")]
    passwords = [login["transport/auth/usrpwd"]["password"] for login in logins]
    assert len(passwords) == 5  # logger, launcher, three agents (the world, the router, has none)
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    assert _files_holding(launch.run_dir, passwords) == []
    assert launch.wait_until(lambda: launch.sim_time() >= 4.0, timeout_s=60)  # agent-3.2 has joined
    assert _files_holding(launch.run_dir, passwords) == []
    res = launch.wait(timeout_s=120)
    assert res.exit_code == 0, res.summary["failure"]
    (rejoin,) = res.summary["faults"][0]["rejoins"]
    assert rejoin["ticks_to_rejoin"] == 0  # the fresh agent logged in and rejoined on its tick
    assert res.summary["processes"]["agent-3.2"]["exit_code"] == 0
