"""End-to-end runs: every robot its own process over Zenoh (issue: the spine)."""

from __future__ import annotations

import contextlib
import json
import math
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import zenoh

from formation_swarm.launch.launcher import KillAt, Launch, RunResult
from formation_swarm.protocol.codec import MAX_PAYLOAD_BYTES
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Command
from formation_swarm.protocol.session import make_config
from formation_swarm.world.stalls import STALL_AFTER_MISSES
from tests.helpers import RERUN, SCENARIOS, our_processes, rrd_rows, run_together
from tests.helpers.replica import replay

FIG11 = SCENARIOS / "fig11_obstacles.toml"
TURN = SCENARIOS / "fig7_turn_vn_dynamic.toml"


@pytest.fixture(scope="module")
def fig11_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """Fig. 11 once, lockstep, with the logger; shared by several tests."""
    with Launch(FIG11, out=tmp_path_factory.mktemp("fig11"), progress=lambda _l: None) as launch:
        return launch.wait(timeout_s=300)


PROGRESS = re.compile(r"\[swarm\] tick (\d+)/(\d+) \((\d+)%\), sim ([\d.]+) s")  # a progress line


def _events(summary: dict, robot: int) -> list[tuple[str, float]]:
    return [(e["formation"], e["time_s"]) for e in summary["formation_events"] if e["robot"] == robot]


def test_fig11_one_process_per_robot_triangle_line_triangle(fig11_run: RunResult) -> None:
    s = fig11_run.summary
    assert fig11_run.exit_code == 0
    pids = {name: p["pid"] for name, p in s["processes"].items()}
    agent_pids = [pids[f"agent-{r}"] for r in (1, 2, 3)]
    assert len(set(agent_pids) | {pids["world"], pids["logger"], os.getpid()}) == 6
    assert all(p["exit_code"] == 0 for p in s["processes"].values())
    # The obstacles stand at y = 36 m and the leader starts at y = 0, 1.5 m/s.
    obstacle_time = 36.0 / 1.5
    for robot in (1, 2, 3):
        ev = _events(s, robot)
        assert [name for name, _ in ev] == ["line", "triangle"], ev
        line_at, tri_at = ev[0][1], ev[1][1]
        assert line_at < obstacle_time - 3.0  # in line well before the gap
        assert tri_at > obstacle_time  # back to triangle after it
    assert s["collisions"] == 0
    assert s["obstacle_collisions"] == 0
    assert s["min_distance_m"] > s["robot_diameter_m"]
    # Measured (seed 1): R2 RMS 0.52 m, R3 RMS 1.04 m (R3 follows R2, so errors add).
    assert s["followers"]["2"]["rms_m"] < 0.8
    assert s["followers"]["3"]["rms_m"] < 1.5
    assert s["lockstep_misses"] == 0
    assert s["rejected_total"] == 0
    # The leader flies its path to the end, before the 56 s of the scenario run out.
    assert s["end_reason"] == "leader_finished"
    assert s["ended_at_s"] == pytest.approx(s["ticks"] * 0.05)
    assert s["ended_at_s"] < 56.0


def test_recording_verifies_and_reads_back(fig11_run: RunResult) -> None:
    rrd = fig11_run.recording
    done = subprocess.run([RERUN, "rrd", "verify", str(rrd)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    rows = rrd_rows(rrd)
    ticks = fig11_run.summary["ticks"]
    for r in (1, 2, 3):
        assert rows.get(f"/robots/r{r}/trajectory", 0) == ticks
    for r in (2, 3):
        # Telemetry travels in batches; the last one still arrives before the logger closes.
        assert rows.get(f"/robots/r{r}/ekf/target", 0) == ticks
        assert rows.get(f"/robots/r{r}/fis/v_n", 0) == ticks
    assert rrd_rows(rrd, static=True).get("/world/obstacles") == 1


@contextlib.contextmanager
def _cpu_hogs(n: int = 2) -> object:
    """n busy-looping processes beside the run: one per core here."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield
    finally:
        for h in hogs:
            h.kill()
            h.wait()


def test_same_seed_same_digest_other_seed_differs(
    swarm_run: Callable[..., RunResult], swarm_launch: Callable[..., Launch]
) -> None:
    a, c = (
        r.summary
        for r in run_together(
            swarm_launch, (FIG11, {"seed": 7, "logger": False}), (FIG11, {"seed": 8, "logger": False})
        )
    )
    with _cpu_hogs():  # the same run on a loaded machine, each process exec'd rather than forked
        b = swarm_run(FIG11, seed=7, logger=False, fork=False).summary  # timing changes, trajectories must not
    assert a["lockstep_misses"] == b["lockstep_misses"] == 0
    assert a["trajectory_digest"] == b["trajectory_digest"]
    assert a["trajectory_digest"] != c["trajectory_digest"]


def test_forked_roles_are_what_exec_would_start(swarm_launch: Callable[..., Launch]) -> None:
    """Each role forked from the spawner shows its own command line, leads its own
    session, reads /dev/null, writes its log, and left the server's pipes closed."""
    launch = swarm_launch(FIG11, mode="realtime", overrides={"run.duration_s": 30.0}, rt_priority=7)
    assert launch.wait_until(lambda: launch.sim_time() >= 0.5, timeout_s=60)
    for name, pid in launch.pids().items():
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().rstrip(b"\0").decode().split("\0")[0].split(" ")
        assert argv == launch.children[name].argv, name
        assert os.getsid(pid) == pid, name
        fds = {int(fd.name): os.readlink(fd) for fd in Path(f"/proc/{pid}/fd").iterdir()}
        assert fds[0] == "/dev/null", name
        assert fds[1] == fds[2] == str(launch.children[name].log_path), name
        # Its parent is the spawner's server, which ends with the launcher.
        assert Path(f"/proc/{pid}/stat").read_text().split(") ")[1].split()[1] != str(os.getpid()), name
    # The real-time world, every thread of it (Zenoh's too), in the real-time
    # class at the priority asked (swarm run --rt-priority) where this machine
    # allows it; nothing else.
    rt = (
        subprocess.run(
            [sys.executable, "-c", "import os; os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(10))"], check=False
        ).returncode
        == 0
    )
    for name, pid in launch.pids().items():
        tids = [int(t.name) for t in Path(f"/proc/{pid}/task").iterdir()]
        policies = {os.sched_getscheduler(tid) for tid in tids}
        assert policies == ({os.SCHED_RR} if rt and name == "world" else {os.SCHED_OTHER}), name
        assert {os.sched_getparam(tid).sched_priority for tid in tids} == {7 if rt and name == "world" else 0}, name
    launch.stop()


MAIN_SCRIPT = """
import sys
print("the main script ran", flush=True)
from pathlib import Path
from formation_swarm.runtime.spawner import Forked

if __name__ == "__main__":
    argv = [sys.executable, "-m", "formation_swarm.nodes.agent.main", "--help"]
    print("exit", Forked("formation_swarm.nodes.agent.main", argv, Path(sys.argv[1]), {}).wait(60), flush=True)
"""


def test_a_forked_role_does_not_run_the_launchers_main_script_again(tmp_path: Path) -> None:
    """multiprocessing runs the parent's __main__ again in each child; a role needs
    nothing of it (for a benchmark script, that was its imports, 20 ms a child)."""
    script = tmp_path / "launcher_script.py"
    script.write_text(MAIN_SCRIPT)
    out = subprocess.run(
        [sys.executable, str(script), str(tmp_path / "role.log")],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout
    assert out == "the main script ran\nexit 0\n"  # once: in the launcher, not again in its child
    assert (tmp_path / "role.log").read_text().startswith("usage: swarm agent")


def test_an_exit_code_the_fork_server_did_not_report_is_the_childs_own(tmp_path: Path, monkeypatch) -> None:
    """multiprocessing says 255 when it cannot read a child's code from the fork
    server (a suite saw it once, for a world that had said exit code 0): the
    code is then the one the child wrote itself."""
    from formation_swarm.runtime.spawner import UNREPORTED, Forked

    argv = [sys.executable, "-m", "formation_swarm.nodes.agent.main", "--no-such-flag"]  # a usage error: exit 2
    reported = Forked("formation_swarm.nodes.agent.main", argv, tmp_path / "a.log", {})
    assert reported.wait(60) == 2
    assert not reported.unreported
    lost = Forked("formation_swarm.nodes.agent.main", argv, tmp_path / "b.log", {})
    lost._p.join(60)
    monkeypatch.setattr(type(lost._p), "exitcode", property(lambda _p: UNREPORTED))
    assert lost.poll() == 2
    assert lost.unreported
    assert not Path(lost.exit_path).exists()  # no file left behind
    assert not Path(reported.exit_path).exists()


def test_a_run_shorter_than_a_progress_line_still_shows_where_it_ended(
    swarm_run: Callable[..., RunResult],
) -> None:
    """A progress line comes every 2 s; a run that ends sooner used to show
    only its tick 0. The last line now gives the tick it ended at."""
    said: list[str] = []
    res = swarm_run(FIG11, overrides={"run.duration_s": 1.5}, logger=False, progress=said.append)
    assert res.exit_code == 0
    # (tick, of, percent, sim s) of each progress line
    ticks = [m.groups() for line in said if (m := PROGRESS.fullmatch(line))]
    assert len(ticks) == len([line for line in said if line.startswith("[swarm] tick ")])  # every one has the shape
    assert ticks[0] == ("0", "30", "0", "0.0")
    assert ticks[-1] == ("30", "30", "100", "1.5")


def test_runs_with_observation_and_formation_code_drops_are_reproducible(
    swarm_run: Callable[..., RunResult], swarm_launch: Callable[..., Launch]
) -> None:
    """Whether a message drops is decided on its link's own sequence number, which
    nothing timed by the wall clock (the world's status messages) may advance."""
    lossy = {"links.obs_drop": 0.3, "links.formation_drop": 0.3}
    a, clean = (
        r.summary
        for r in run_together(
            swarm_launch,
            (FIG11, {"seed": 3, "logger": False, "overrides": lossy}),
            (FIG11, {"seed": 3, "logger": False}),
        )
    )
    with _cpu_hogs():  # another timing: status messages fall on other ticks
        b = swarm_run(FIG11, seed=3, logger=False, overrides=lossy).summary
    assert a["lockstep_misses"] == b["lockstep_misses"] == 0
    assert a["trajectory_digest"] == b["trajectory_digest"]
    obs = {k: v for k, v in a["links"].items() if k.startswith("obs:")}
    assert obs == {k: v for k, v in b["links"].items() if k.startswith("obs:")}  # the same drops, link by link
    # (A formation code the leader sends as the run ends may arrive or not: its counts are not compared.)
    dropped = {k: v["dropped"] for k, v in a["links"].items() if k.startswith(("obs:", "formation:")) and v["dropped"]}
    assert len(dropped) == 5, a["links"]  # 3 observation links and 2 formation links all lost messages
    assert a["trajectory_digest"] != clean["trajectory_digest"]


@pytest.mark.parametrize(
    ("scenario", "overrides"),
    [(TURN, {}), (FIG11, {"links.obs_drop": 0.2, "links.formation_drop": 0.3, "links.cmd_drop": 0.1})],
    ids=["turn", "fig11-drops"],
)
def test_a_lockstep_run_is_its_one_process_replica(
    swarm_run: Callable[..., RunResult], scenario: Path, overrides: dict
) -> None:
    """The processes add nothing to a lockstep run's figures: tests/helpers/replica.py,
    which tests/unit/studies/test_published.py and mutation testing use, is the same run."""
    real = swarm_run(scenario, seed=4, logger=False, overrides=overrides).summary
    again = replay(scenario, 4, overrides)
    assert real["lockstep_misses"] == 0
    assert real["ticks"] == again["ticks"]
    assert real["trajectory_digest"] == again["trajectory_digest"]
    for rid, m in real["followers"].items():
        assert m["rms_m"] == again["followers"][rid]["rms_m"]
        assert (m["frames"], m["seen_ticks"]) == (
            again["followers"][rid]["frames"],
            again["followers"][rid]["seen_ticks"],
        )
        assert m["acquired"] is True
    # (Within one tick, the world lists formation events in the order the answers came.)
    by_tick = sorted(real["formation_events"], key=lambda e: (e["tick"], e["robot"]))
    assert by_tick == sorted(again["formation_events"], key=lambda e: (e["tick"], e["robot"]))


def test_formation_changes_through_30_percent_drops(swarm_launch: Callable[..., Launch]) -> None:
    # Seed 2: at 30% the drops hit two of the four changes (measured delays
    # 0.05, 0.05, 0.10, 0.15 s), so re-sending is exercised, not just bounded.
    clean, lossy = (
        r.summary
        for r in run_together(
            swarm_launch,
            (FIG11, {"seed": 2, "logger": False}),
            (FIG11, {"seed": 2, "logger": False, "overrides": {"links.formation_drop": 0.3}}),
        )
    )

    def delays(s: dict) -> list[float]:
        leader = dict((n, t) for n, t in _events(s, 1))
        return [t - leader[n] for r in (2, 3) for n, t in _events(s, r)]

    d_clean, d_lossy = delays(clean), delays(lossy)
    assert len(d_lossy) == 4  # both followers went to line and back
    assert all(d == pytest.approx(0.05) for d in d_clean)  # one tick: the next observation
    # Per tick a code gets through with p = 0.7: 10 straight losses has p = 6e-6.
    assert max(d_lossy) <= 0.5 + 1e-9, d_lossy
    assert max(d_lossy) > 0.05 + 1e-9, d_lossy  # a drop did delay a change
    dropped = [v["dropped"] for k, v in lossy["links"].items() if k.startswith("formation:")]
    received = [v["received"] for k, v in lossy["links"].items() if k.startswith("formation:")]
    assert 0.25 < sum(dropped) / sum(received) < 0.35
    assert lossy["collisions"] == 0


def test_killed_follower_is_stopped_and_the_run_completes(swarm_run: Callable[..., RunResult]) -> None:
    kill_at = 3.0
    res = swarm_run(
        FIG11, mode="realtime", logger=False, kills=[KillAt("agent-3", kill_at)], overrides={"run.duration_s": 7.0}
    )
    s = res.summary
    assert res.exit_code == 0
    assert s["ticks"] == 140  # the whole 7 s ran
    (death,) = s["deaths"]
    assert death["robot"] == 3
    killed = next(e for e in s["events"] if e["event"] == "killed")
    # The world stops it at the kill's tick, before that tick's observations,
    # whenever the launcher's SIGKILL lands (it executes the world's call).
    assert death["tick"] == killed["tick"] == round(kill_at / 0.05)
    assert death["time_s"] == killed["sim_time_s"] == kill_at
    assert s["parts"]["world"]["final_poses"]["3"] == death["pose"]  # never moved again
    assert s["processes"]["agent-3"]["exit_code"] == -signal.SIGKILL
    assert s["parts"]["world"]["final_poses"]["1"][1] > 9.0  # the leader flew on


def _flood(sess: zenoh.Session, keys: list[str], payload: Callable[[int], bytes], n: int) -> None:
    """Put ``payload(i)`` on every key, n times."""
    pubs = [sess.declare_publisher(k, congestion_control=zenoh.CongestionControl.BLOCK) for k in keys]
    # What is published before a subscriber matched is lost: wait for all.
    deadline = time.monotonic() + 30
    while not all(p.matching_status.matching for p in pubs):
        unmatched = [k for k, p in zip(keys, pubs, strict=True) if not p.matching_status.matching]
        assert time.monotonic() < deadline, unmatched
        time.sleep(0.01)
    for i in range(n):
        for pub in pubs:
            pub.put(payload(i))


def test_random_bytes_on_every_key_kill_nothing(swarm_launch: Callable[..., Launch]) -> None:
    # Authentication off: this is the receivers' own wall (tests/system/test_attacks.py has the router's).
    launch = swarm_launch(FIG11, mode="realtime", overrides={"run.duration_s": 4.0}, auth=False)
    assert launch.wait_until(lambda: launch.sim_time() >= 0.5, timeout_s=60)
    keys = Keys(launch.run_id)
    targets = [keys.robot(r, k) for r in (1, 2, 3) for k in ("obs", "cmd", "telemetry")]
    targets += [keys.codes, *(f"{keys.prefix}/robot/{r}/formation" for r in (1, 2, 3)), keys.truth, keys.status]
    rng = np.random.default_rng(0)
    n = 20
    crafted = [
        Command(
            sender=2, seq=1, tick=1, left_mps=math.inf, right_mps=1.0, formation=0, done=False
        ).to_bytes(),  # NaN/inf
        b"\x96\x02\x07\x02\x01\x01\xcb" + b"\x00" * 8,  # unknown version
        b"\xc1",  # invalid msgpack
        b"\x00" * (MAX_PAYLOAD_BYTES + 1),  # oversized: reaches the decoders, which count it
    ]
    huge = b"\x00" * 70_000  # above the low-latency transport's 49,152-byte frame
    # Our sessions stay open until the run ends: closing one drops what it still holds.
    with (
        zenoh.open(make_config("client", [launch.endpoint])) as ours,
        zenoh.open(make_config("client", [launch.endpoint], lowlatency=False)) as plain,
    ):
        # From a default-transport client the router drops such frames on the way
        # in: forwarded, one would close an agent's link and the world would
        # take that robot for dead ...
        _flood(plain, targets, lambda _i: huge, 2)
        _flood(ours, targets, lambda i: crafted[i] if i < len(crafted) else rng.bytes(int(rng.integers(0, 200))), n)
        # ... and from a low-latency client the router closes that client's link only.
        _flood(ours, targets, lambda _i: huge, 1)
        res = launch.wait(timeout_s=120)
    s = res.summary
    assert res.exit_code == 0
    assert all(p["exit_code"] == 0 for p in s["processes"].values()), s["processes"]
    assert s["deaths"] == [], s["deaths"]
    rej = {name: sum(v.values()) for name, v in s["rejected"].items()}
    # The world decodes commands (3 keys); each agent its inbox (its obs, cmd,
    # telemetry and formation keys, and the codes' key) and the status key; the
    # logger truth, status, 3 telemetry keys and the codes' key (the leader's switches).
    assert rej["world"] == 3 * n
    for r in (1, 2, 3):
        assert rej[f"agent-{r}"] == 6 * n
    assert rej["logger"] == 6 * n
    assert s["rejected_total"] == 27 * n
    assert s["rejected"]["world"]["oversized"] == 3


def test_logger_sigkill_keeps_the_recording_up_to_the_kill(swarm_run: Callable[..., RunResult]) -> None:
    from rerun.chunk import RrdReader

    kill_at = 4.0
    res = swarm_run(FIG11, mode="realtime", kills=[KillAt("logger", kill_at)], overrides={"run.duration_s": 6.0})
    assert res.exit_code == 0
    killed = next(e for e in res.summary["events"] if e["event"] == "killed")
    last = -1.0
    for chunk in RrdReader(str(res.recording)).stream():
        if str(chunk.entity_path) == "/robots/r1/pose" and not chunk.is_static:  # static: how it is drawn
            times = chunk.to_record_batch().column("sim_time").to_pylist()
            last = max([last, *[t.total_seconds() if hasattr(t, "total_seconds") else t / 1e9 for t in times]])
    assert last >= killed["sim_time_s"] - 1.0, (last, killed)


@pytest.mark.parametrize("mode", ["realtime", "lockstep"])
def test_every_process_exits_within_2s_of_sigterm(swarm_launch: Callable[..., Launch], mode: str) -> None:
    # A long straight path: the lockstep run must still be going when it is stopped.
    long_run = {"run.duration_s": 600.0, "leader.waypoints": [[0.0, 0.0], [0.0, 1000.0]]}
    launch = swarm_launch(FIG11, mode=mode, overrides=long_run)
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    stopping = time.monotonic()
    launch.stop(graceful_first=False)
    for name, child in launch.children.items():
        assert child.proc is not None, name
        assert child.proc.returncode is not None, name
        assert child.exited_at is not None, name
        assert child.exited_at >= stopping, name  # it ran until the stop
        # The world goes first; an agent may leave on its "done" before its own SIGTERM is sent.
        sent = child.stop_sent_at if child.stop_sent_at is not None else stopping
        assert child.exited_at - sent <= 2.0, (name, child.exited_at - sent)
        assert child.proc.returncode in (0, 128 + signal.SIGTERM), (name, child.proc.returncode)


def test_lockstep_deadline_counts_a_frozen_agent_then_stalls_it_and_goes_on(
    swarm_launch: Callable[..., Launch],
) -> None:
    """Agent 3 frozen (SIGSTOP: its token stays, it answers nothing): each tick
    waits out the deadline for it, STALL_AFTER_MISSES times in a row; then it is
    stalled and the run goes on at the others' pace. Resumed, it answers again
    and is waited for again. No fault of the schedule froze it: the run is not
    reproducible, and fails."""
    deadline_s = 0.05
    launch = swarm_launch(
        FIG11,
        logger=False,
        overrides={
            "run.lockstep_deadline_s": deadline_s,
            "run.duration_s": 120.0,  # long enough to be running still when frozen
            "leader.waypoints": [[0.0, 0.0], [0.0, 1000.0]],
        },
    )
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    pid = launch.pids()["agent-3"]
    os.kill(pid, signal.SIGSTOP)  # alive (its token stays) but answers nothing
    try:
        # Status comes every 0.25 s of wall time: the second one from now was sent after the freeze.
        for _ in range(2):
            seen = launch.sim_time()
            assert launch.wait_until(lambda seen=seen: launch.sim_time() > seen, timeout_s=60)
        frozen_at = launch.sim_time()
        assert launch.wait_until(lambda: launch.sim_time() >= frozen_at + 1.0, timeout_s=60)
    finally:
        os.kill(pid, signal.SIGCONT)
    res = launch.wait(timeout_s=120)
    s = res.summary
    assert res.exit_code == 1
    assert s["ticks"] == 2400  # the whole 120 s ran
    assert s["lockstep_misses"] >= STALL_AFTER_MISSES
    [late] = [e for e in s["not_reproducible"] if e["robot"] == 3]
    assert (late["misses"] >= STALL_AFTER_MISSES, late["deadline_s"]) == (True, deadline_s)
    # (On a loaded machine a thawed agent, or another, can miss a 50 ms deadline again.)
    robot_3 = [e for e in s["stalls"] if e["robot"] == 3]
    assert [e["event"] for e in robot_3[:2]] == ["stalled", "answering again"]
    assert robot_3[0]["misses"] == STALL_AFTER_MISSES
    assert s["processes"]["agent-3"]["exit_code"] == 0


def test_every_process_exits_within_2s_of_the_run_end(swarm_run: Callable[..., RunResult]) -> None:
    res = swarm_run(TURN, logger=True)
    procs = res.summary["processes"]
    assert all(p["exit_code"] == 0 for p in procs.values()), procs
    # Nobody needed a signal: each left on the world's "done".
    assert all(p["exit_after_stop_s"] is None for p in procs.values()), procs


@pytest.mark.parametrize("after_s", [0.3, 0.6, 1.0])
def test_ctrl_c_from_a_terminal_while_swarm_run_starts_prints_no_traceback(tmp_path: Path, after_s: float) -> None:
    """A terminal's Ctrl-C goes to its whole process group: the launcher and the
    spawner's server, which may still be importing the roles' modules (here
    0.2-0.8 s after the start). The server ignores it; the launcher stops the run
    and says so in one line."""
    before = {pid for pid, _ in our_processes()}
    cmd = [sys.executable, "-m", "formation_swarm.cli", "run", str(FIG11), "--out", str(tmp_path / "r")]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    time.sleep(after_s)  # the moment of the Ctrl-C is the test's subject
    os.killpg(proc.pid, signal.SIGINT)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 130, out
    assert "Traceback" not in out
    assert "Fatal Python error" not in out
    assert "KeyboardInterrupt" not in out
    # One line says so: while starting, the last; once running, before the result block.
    assert [line for line in out.splitlines() if line.startswith(("[swarm] interrupted", "interrupted"))], out

    # Every process it had started stopped on the signal: none needed the kill after the grace
    # (a start cut in two had left a world the launcher did not know of, SIGKILLed 2 s later).
    summary = tmp_path / "r" / "summary.json"
    if summary.exists():  # none when the Ctrl-C came before any process started (tests/system/test_interrupt.py)
        events = json.loads(summary.read_text())["events"]
        assert not [e for e in events if e.get("event") == "killed after stop timeout"], events

    def mine() -> list[str]:  # this run's roles: their command lines name its folder
        return [c for p, c in our_processes() if p not in before and str(tmp_path) in c]

    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and mine():
        time.sleep(0.05)
    assert mine() == []


@pytest.mark.parametrize("when", ["starting", "running", "sigkill"])
def test_ctrl_c_on_swarm_run_leaves_no_process(tmp_path: Path, when: str) -> None:
    """Ctrl-C while the processes start or run: a clean stop and a summary. SIGKILL
    (no summary can be written): every process still goes, each forked from the
    spawner, whose server ends with the launcher (formation_swarm.runtime.spawner)."""
    before = {pid for pid, _ in our_processes()}
    cmd = [
        sys.executable,
        "-m",
        "formation_swarm.cli",
        "run",
        str(FIG11),
        "--mode",
        "realtime",
        "--out",
        str(tmp_path / "r"),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: queue.SimpleQueue[str] = queue.SimpleQueue()
    reader = threading.Thread(target=lambda: [lines.put(line) for line in proc.stdout], daemon=True)  # type: ignore[union-attr]
    reader.start()
    deadline = time.monotonic() + 60

    def mine() -> list[int]:  # this run's processes: their command lines name its folder
        return [p for p, cmd in our_processes() if p not in before and str(tmp_path) in cmd]

    while time.monotonic() < deadline and len(mine()) < 5:
        time.sleep(0.02)
    assert len(mine()) == 5
    if when != "starting":  # wait for a progress line past tick 0
        seen = ""
        while time.monotonic() < deadline and not (
            seen.startswith("[swarm] tick") and not seen.startswith("[swarm] tick 0/")
        ):
            with contextlib.suppress(queue.Empty):
                seen = lines.get(timeout=0.1)
        assert seen.startswith("[swarm] tick"), seen
    t0 = time.monotonic()
    if when == "sigkill":
        proc.kill()
        proc.wait(timeout=30)
        while time.monotonic() < t0 + 15.0 and mine():  # SIGTERM on the parent's death, then their 2 s stop
            time.sleep(0.05)
        assert mine() == []
        return
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=30)
    reader.join(timeout=5)
    assert proc.returncode == 130
    assert time.monotonic() - t0 < 10.0  # about 2 s (the processes' stop), 3x on a loaded machine
    assert mine() == []
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["interrupted"] is True
    assert summary["end_reason"] == "interrupted"
    rest = []
    while not lines.empty():
        rest.append(lines.get())
    said = [line for line in rest if line.startswith("[swarm] interrupted")]
    assert said, rest
    # No progress line after it: the last status seen is older than where the run stopped, and the result says that.
    assert not any(line.startswith("[swarm] tick") for line in rest[rest.index(said[0]) :]), rest
