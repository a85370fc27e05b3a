"""Roles started by hand (``swarm world|agent|logger``): what they print, the
peers deadline, stop signals while connecting, and the world's summary.json.

Every process runs on loopback with an explicit endpoint and its own run id;
every wait has a deadline; every process is reaped in ``finally``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

import formation_swarm
from formation_swarm.launch.launcher import RunResult, free_port
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import SCENARIOS

TURN = SCENARIOS / "fig7_turn_vn_dynamic.toml"
PEERS_TIMEOUT_S = 3.0
HEADROOM = 3.0  # a loaded machine (2 shared cores): 3x the target
MODULES = {
    "world": "formation_swarm.nodes.world.main",
    "agent": "formation_swarm.nodes.agent.main",
    "logger": "formation_swarm.nodes.logger.main",
    "router": "formation_swarm.nodes.router",
}


@dataclass
class Proc:
    name: str
    popen: subprocess.Popen[bytes]
    out: Path
    err: Path
    started_at: float
    exited_at: float | None = None

    def wait(self, timeout_s: float) -> int:
        code = self.popen.wait(timeout=timeout_s)
        self.exited_at = self.exited_at or time.monotonic()
        return code

    def lines(self, stream: str = "out") -> list[str]:
        return (self.out if stream == "out" else self.err).read_text().splitlines()


@pytest.fixture
def start(tmp_path: Path) -> Iterator[Callable[..., Proc]]:
    """Start a role (``start("agent-2", "agent", *args)``); all reaped at teardown."""
    procs: list[Proc] = []

    def run(name: str, role: str, *args: str) -> Proc:
        out, err = tmp_path / f"{name}.out", tmp_path / f"{name}.err"
        with out.open("wb") as o, err.open("wb") as e:
            popen = subprocess.Popen(
                [sys.executable, "-m", MODULES[role], *args], stdout=o, stderr=e, stdin=subprocess.DEVNULL
            )
        proc = Proc(name, popen, out, err, time.monotonic())
        procs.append(proc)
        return proc

    try:
        yield run
    finally:
        for p in procs:
            if p.popen.poll() is None:
                p.popen.terminate()
        for p in procs:
            try:
                p.popen.wait(timeout=5)
            except subprocess.TimeoutExpired:
                p.popen.kill()
                p.popen.wait()


def _run_id(tag: str) -> str:
    return f"roles-{tag}-{uuid.uuid4().hex[:8]}"


def _turn(tmp_path: Path) -> Path:
    """The turning scenario, copied: every process's command line then names
    the test's folder, which the suite's no-process-left guard looks for."""
    copy = tmp_path / "turn.toml"
    copy.write_text(TURN.read_text())
    return copy


def test_mismatched_run_ids_give_up_at_the_deadline_with_one_line(tmp_path: Path, start: Callable[..., Proc]) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    world_run, other_run = _run_id("world"), _run_id("typo")
    deadline = ["--peers-timeout", str(PEERS_TIMEOUT_S)]
    common = ["--scenario", str(_turn(tmp_path)), *deadline]
    # A router of its own, up first: each role then connects as soon as its
    # imports are done, however long those take (the logger's, with Rerun,
    # longest), and not only while the world still waits.
    router = start("router", "router", "--listen", endpoint)
    _first_lines(router)
    as_client = ["--zenoh-mode", "client", "--connect", endpoint]
    world = start("world", "world", *common, "--run", world_run, *as_client, "--expect-logger")
    agent = start("agent-2", "agent", *common, "--id", "2", "--run", other_run, "--connect", endpoint)
    logger = start(
        "logger", "logger", *common, "--run", other_run, "--connect", endpoint, "--out", str(tmp_path / "rec.rrd")
    )
    # The deadline starts in main(), after the imports (1-2 s alone, more on a
    # loaded machine): the wait is timed from the first line, printed then.
    printed = _first_lines(world, agent, logger)
    for p in (world, agent, logger):
        assert p.wait(timeout_s=60) == process_mod.EXIT_NO_PEERS, p.lines("err")
        assert p.exited_at - p.started_at >= PEERS_TIMEOUT_S  # type: ignore[operator]
        waited = p.exited_at - printed[p.name]  # type: ignore[operator]
        assert waited <= PEERS_TIMEOUT_S * HEADROOM, (p.name, waited)
        (connected,) = p.lines("out")
        assert f"waiting up to {PEERS_TIMEOUT_S:g} s" in connected, connected
        (gave_up,) = p.lines("err")
        assert gave_up.startswith(f"{p.name.replace('-', ' ')}: gave up after {PEERS_TIMEOUT_S:g} s: "), gave_up
        assert "check --run and --connect, and with --auth that its login" in gave_up, gave_up
    (line,) = world.lines("err")
    assert f"no agent for robots 1, 2 and no logger in run {world_run!r}" in line, line
    assert endpoint in line
    for p in (agent, logger):
        (line,) = p.lines("err")
        assert f"no world of run {other_run!r}" in line, line
        assert endpoint in line, line


def _first_lines(*procs: Proc, timeout_s: float = 180.0) -> dict[str, float]:  # imports: 60 s seen at load 17
    """When each process printed its first line (``time.monotonic()``)."""
    seen: dict[str, float] = {}
    deadline = time.monotonic() + timeout_s
    while len(seen) < len(procs):
        for p in procs:
            if p.name not in seen and p.out.stat().st_size > 0:
                seen[p.name] = time.monotonic()
        assert time.monotonic() < deadline, f"no first line from {[p.name for p in procs if p.name not in seen]}"
        time.sleep(0.01)
    return seen


def _inside_zenoh_open(pid: int) -> bool:
    """The role's stop handlers are installed (SIGTERM caught) and Zenoh's
    runtime threads exist: it is opening its session, which, with no router
    to reach, it cannot finish."""
    try:
        caught = int(
            next(
                line.split()[1]
                for line in Path(f"/proc/{pid}/status").read_text().splitlines()
                if line.startswith("SigCgt:")
            ),
            16,
        )
        names = {(t / "comm").read_text().strip() for t in Path(f"/proc/{pid}/task").iterdir()}
    except (OSError, StopIteration):
        return False
    return bool(caught & (1 << (signal.SIGTERM - 1))) and any(n.startswith(("net-", "app-")) for n in names)


@pytest.mark.parametrize(
    ("role", "sig"),
    [("world", signal.SIGTERM), ("agent", signal.SIGTERM), ("logger", signal.SIGTERM), ("agent", signal.SIGINT)],
)
def test_stop_signal_while_connecting_to_an_absent_router(
    tmp_path: Path, start: Callable[..., Proc], role: str, sig: signal.Signals
) -> None:
    absent = f"tcp/127.0.0.1:{free_port()}"  # nothing listens there
    args = ["--scenario", str(_turn(tmp_path)), "--run", _run_id(role), "--connect", absent]
    args += {"world": ["--zenoh-mode", "client"], "agent": ["--id", "2"], "logger": ["--out", str(tmp_path / "r.rrd")]}[
        role
    ]
    p = start(role, role, *args)
    deadline = time.monotonic() + 60
    while not _inside_zenoh_open(p.popen.pid):
        assert p.popen.poll() is None, p.lines("err")
        assert time.monotonic() < deadline, "the role never started to connect"
        time.sleep(0.01)
    sent = time.monotonic()
    os.kill(p.popen.pid, sig)
    code = p.wait(timeout_s=30)
    took = time.monotonic() - sent
    assert code == 128 + sig, (code, p.lines("err"))
    assert took <= 2.0 * HEADROOM, took  # under 0.5 s quiet; 3.4 s seen at a load of 17
    (line,) = p.lines("out")
    assert f"stopped by {sig.name} while connecting to {absent}" in line, line


def _short_turn(path: Path) -> Path:
    """The turning scenario with a 4.5 m path: the leader finishes it at ~3 s
    of sim time, long before the duration (44 s)."""
    sc = scenario_mod.load(TURN, {"leader.waypoints": [[0.0, 0.0], [0.0, 4.5]]})
    path.write_text(scenario_files.dumps(sc.raw))
    return path


def test_world_by_hand_with_out_writes_the_summary_of_swarm_run(
    tmp_path: Path, start: Callable[..., Proc], swarm_run: Callable[..., RunResult]
) -> None:
    scenario = _short_turn(tmp_path / "short.toml")
    launched = swarm_run(scenario, logger=False).summary

    endpoint, run, out = f"tcp/127.0.0.1:{free_port()}", _run_id("hand"), tmp_path / "by-hand"
    common = ["--scenario", str(scenario), "--run", run]
    world = start("world", "world", *common, "--listen", endpoint, "--out", str(out))
    agents = [
        start(
            f"agent-{r}",
            "agent",
            *common,
            "--id",
            str(r),
            "--connect",
            endpoint,
            "--stats",
            str(tmp_path / f"agent-{r}.json"),
        )
        for r in (1, 2)
    ]
    for p in (world, *agents):
        assert p.wait(timeout_s=120) == 0, p.lines("err")
    hand = json.loads((out / "summary.json").read_text())

    assert set(hand) == set(launched) - {"ticks_seen"}  # the launcher's own: the last tick its status showed
    for s in (hand, launched):
        assert s["end_reason"] == summary_mod.LEADER_FINISHED
        assert 2.0 < s["ended_at_s"] < 5.0  # 4.5 m at 1.5 m/s, plus the last approach
        assert s["exit_code"] == 0
        assert s["version"] == formation_swarm.__version__
        assert s["git_commit"] == summary_mod.git_commit()
    # Same scenario, same seed, lockstep: the same run, tick for tick.
    assert hand["ticks"] == launched["ticks"] == round(hand["ended_at_s"] / 0.05)
    assert hand["trajectory_digest"] == launched["trajectory_digest"]
    assert hand["ended_at_s"] == launched["ended_at_s"]
    assert scenario_mod.load(out / "scenario.toml").raw == scenario_mod.load(scenario).raw
    assert hand["processes"]["world"]["exit_code"] == 0

    # One line each: connected, started, ended (with where the results went).
    connected, started, ended = world.lines("out")
    assert connected.startswith(f"world: router, listening on {endpoint}; run {run}: waiting up to 60 s"), connected
    assert started.startswith(f"world: run {run} started"), started
    assert f"run {run} ended (the leader reached its last waypoint at t=" in ended, ended
    assert str(out / "summary.json") in ended
    for r, p, role in zip((1, 2), agents, ("leader", "follower of robot 1"), strict=True):
        connected, started, ended = p.lines("out")
        assert connected.startswith(f"agent {r}: connected to {endpoint}; run {run}, {role}: waiting up to "), connected
        assert started == f"agent {r}: run {run} started"
        assert f"ended (the world said done), exit code 0, {hand['ticks']} observations answered" in ended, ended
        assert str(tmp_path / f"agent-{r}.json") in ended
        assert p.lines("err") == []


def _git(root: Path, *files: tuple[str, str]) -> None:
    for name, text in files:
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)


def test_git_commit_of_a_checkout_a_worktree_packed_refs_and_none(tmp_path: Path) -> None:
    a, b = "a" * 40, "b" * 40
    repo = tmp_path / "repo"
    _git(repo, (".git/HEAD", "ref: refs/heads/main\n"), (".git/refs/heads/main", a + "\n"))
    assert summary_mod.git_commit(repo) == a
    # A worktree: .git is a file; its HEAD names a branch kept, packed, in the main repository.
    wt = tmp_path / "wt"
    _git(
        repo,
        (".git/worktrees/wt/HEAD", "ref: refs/heads/topic\n"),
        (".git/worktrees/wt/commondir", "../..\n"),
        (".git/packed-refs", f"# pack-refs with: peeled\n{b} refs/heads/topic\n"),
    )
    _git(wt, (".git", f"gitdir: {repo / '.git/worktrees/wt'}\n"))
    assert summary_mod.git_commit(wt) == b
    _git(repo, (".git/HEAD", b + "\n"))  # detached
    assert summary_mod.git_commit(repo) == b
    _git(repo, (".git/HEAD", "ref: refs/heads/gone\n"))
    assert summary_mod.git_commit(repo) is None
    assert summary_mod.git_commit(tmp_path / "nothing") is None


def test_a_router_signalled_again_while_it_stops_still_exits_0(tmp_path: Path) -> None:
    """Ctrl-C, then more of them while it closes (a user's impatience, or a
    ``timeout`` passing signals on): the router stops once, with exit code 0."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "router.out"
    with out.open("wb") as o:
        router = subprocess.Popen(
            [sys.executable, "-m", "formation_swarm.cli", "router", "--listen", endpoint],
            stdout=o,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        )
    try:
        deadline = time.monotonic() + 60
        while "listening on" not in out.read_text() and time.monotonic() < deadline:
            assert router.poll() is None, out.read_text()
            time.sleep(0.05)
        assert "listening on" in out.read_text()
        sent = 0
        # The first few 1 ms apart: a router that closes in a few ms must still get
        # a second one while it closes. Then for up to 4 s, until it has exited.
        while router.poll() is None and sent < 200:
            router.send_signal(signal.SIGINT)
            sent += 1
            time.sleep(0.001 if sent < 5 else 0.02)
        code = router.wait(timeout=30)
    finally:
        if router.poll() is None:
            router.kill()
            router.wait()
    assert sent >= 2, "it exited at the first signal: nothing came while it stopped"
    assert code == 0, (code, out.read_text())
    assert out.read_text().splitlines()[-1].startswith("router: stopped by SIGINT after")
