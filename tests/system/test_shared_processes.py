"""Robots that share a process (``run.agents_per_process``): each keeps its own
login and token, its faults act on it alone, and lockstep does not see the layout.

Eleven robots in a line (a leader and ten followers): with K = 10, robots 1-10
share one process and robot 11 has one of its own.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from formation_swarm.launch.launcher import Launch, RunResult
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Command
from tests.system.test_attacks import HUGE_SEQ, put_all, rogue

pytestmark = pytest.mark.slow

FIG11 = "fig11_obstacles"
LINE = {"run.robots": 11, "leader.formation": "line", "controller.lookahead_m": 1.0}
TICKS = 120  # 6 s of sim time


def _run(swarm_run: Callable[..., RunResult], k: int, **kwargs: Any) -> dict[str, Any]:
    overrides = {**LINE, "run.duration_s": TICKS * 0.05, "run.agents_per_process": k, **kwargs.pop("overrides", {})}
    res = swarm_run(FIG11, logger=False, overrides=overrides, **kwargs)
    assert res.exit_code == 0, res.summary.get("failure")
    return res.summary


def _answered(s: dict[str, Any]) -> dict[int, int]:
    return {int(name.removeprefix("agent-")): p["answered"] for name, p in s["parts"].items() if name[6:].isdigit()}


def test_a_kill_in_a_shared_process_ends_that_robot_alone_and_lockstep_does_not_see_the_layout(
    swarm_run: Callable[..., RunResult],
) -> None:
    """Kill agent-5 at tick 40, restart agent-9 at 50 (a process of its own from
    tick 70), freeze agent-7 over 40-80: the same run, digest for digest, with a
    process per robot and with ten robots per process; in the shared one,
    robots 1-4, 6, 8 and 10 answer every tick."""
    faults = ["kill agent-5@2s", "restart agent-9@2.5s after=1", "freeze agent-7@2s for=2s"]
    alone, shared = (_run(swarm_run, k, faults=faults) for k in (1, 10))
    assert list(shared["processes"]) == ["world", "agents-1-10", "agents-11", "agent-9.2"]
    assert list(alone["processes"])[1:3] == ["agent-1", "agent-2"]
    for s in (alone, shared):
        assert s["ticks"] == TICKS
        assert [(d["robot"], d["cause"], d["tick"]) for d in s["deaths"]] == [(5, "killed", 40), (9, "killed", 50)]
        assert (s["lockstep_misses"], s["not_reproducible"]) == (0, [])
    assert shared["trajectory_digest"] == alone["trajectory_digest"]
    assert shared["robot_digests"] == alone["robot_digests"]
    answered = _answered(shared)
    assert {r: answered[r] for r in (1, 2, 3, 4, 6, 8, 10, 11)} == dict.fromkeys((1, 2, 3, 4, 6, 8, 10, 11), TICKS)
    assert answered[7] == TICKS - 40  # the world sends a frozen robot nothing in lockstep
    assert all(p["exit_code"] == 0 for p in shared["processes"].values()), shared["processes"]
    kill = next(e for e in shared["events"] if e["event"] == "killed" and e["process"] == "agent-5")
    assert kill["in_process"] == "agents-1-10"


@pytest.mark.parametrize("robots", [3, 10])
def test_lockstep_digests_do_not_depend_on_the_robots_per_process(
    swarm_run: Callable[..., RunResult], robots: int
) -> None:
    """fig11 as shipped (3 robots) and ten robots in a line, K = 1 and K = 10."""
    extra = {} if robots == 3 else {**LINE, "run.robots": robots, "run.duration_s": 5.0}
    digests = []
    for k in (1, 10):
        res = swarm_run(FIG11, logger=False, overrides={**extra, "run.agents_per_process": k})
        assert res.exit_code == 0, res.summary.get("failure")
        digests.append((res.summary["trajectory_digest"], res.summary["robot_digests"]))
        assert len(res.summary["processes"]) == 1 + (robots if k == 1 else 1)
        assert not (res.run_dir / "control").exists()  # no fault, no call to a shared process: no control/
    assert digests[0] == digests[1]


def test_a_freeze_in_a_shared_process_pauses_that_robot_alone(swarm_run: Callable[..., RunResult]) -> None:
    """Real time, agent-5 frozen for 2 s (40 ticks) of 6: its observations wait in
    its inbox (after the thaw it answers the newest and skips the rest), while
    the nine robots beside it in its process answer on."""
    s = _run(swarm_run, 10, mode="realtime", faults=["freeze agent-5@2s for=2s"])
    parts = {r: s["parts"][f"agent-{r}"] for r in range(1, 12)}
    assert s["deaths"] == []
    assert parts[5]["answered"] <= TICKS - 30
    assert parts[5]["superseded"] >= 30
    others = [r for r in range(1, 11) if r != 5]
    assert min(parts[r]["answered"] for r in others) >= TICKS - 10, {r: parts[r]["answered"] for r in others}
    assert [e["process"] for e in s["events"] if e["event"] in ("frozen", "thawed")] == ["agent-5", "agent-5"]


def test_a_robots_login_writes_its_own_keys_only_when_its_process_is_shared(
    swarm_launch: Callable[..., Launch], tmp_path: Path
) -> None:
    """Robot 5's login, used from outside while robots 1-10 share a process,
    puts absurd commands (wheel speeds of 1e308 m/s) for robots 4, 5 and 6.
    Robot 5's reach the world, which refuses each, and agent 5's inbox
    (robot/5/*), which counts each as not its key; robots 4's and 6's are
    dropped by the router: neither the world nor their agents hear one."""
    long = {**LINE, "run.duration_s": 60.0, "leader.waypoints": [[0.0, 0.0], [0.0, 1000.0]]}
    launch = swarm_launch(FIG11, logger=False, overrides={**long, "run.agents_per_process": 10})
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=120)
    k = Keys(launch.run_id)
    tick = int(launch.sim_time() / 0.05) + 1

    def forged(robot: int) -> bytes:
        return Command(
            sender=robot, seq=HUGE_SEQ, tick=tick, left_mps=1e308, right_mps=1e308, formation=0, done=False
        ).to_bytes()

    own = [(k.cmd(5), forged(5))]
    others = [(k.cmd(4), forged(4)), (k.cmd(6), forged(6))]
    with rogue(launch, "agent-5") as sess:
        put_all(sess, own + others, rounds=10, witness=k.alive("world", 0))
        until = launch.sim_time() + 1.0  # the puts on their way: the router forwards them in order
        assert launch.wait_until(lambda: launch.sim_time() >= until, timeout_s=60)
        launch.interrupt()
        res = launch.wait(timeout_s=120)
    s = res.summary
    rejected = s["rejected"]
    assert set(rejected) == {"world", "agent-5"}, rejected  # no other robot heard a thing
    assert sum(rejected["world"].values()) == 10, rejected  # robot 5's key: written, and refused
    assert rejected["agent-5"] == {"unexpected key": 10}
    assert res.exit_code == 130  # interrupted, once the forgeries had passed
    assert list(s["processes"]) == ["world", "agents-1-10", "agents-11"]
