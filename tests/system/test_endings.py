"""Every ending told as it happened: a run whose processes, folder or disk
fail under it says so, at the tick it happened, and leaves nothing
half-written; a run whose robots are cut off in lockstep waits for them.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import signal
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from formation_swarm.launch.console import print_result
from formation_swarm.launch.launcher import Launch, RunResult
from formation_swarm.protocol.keys import Keys
from formation_swarm.runtime.memory import FLOOD_CHECK_S
from formation_swarm.runtime.summary import logger_lost
from formation_swarm.world.stalls import LOST_WAIT_S, STALL_AFTER_MISSES
from tests.system.test_attacks import put_all, rogue

pytestmark = pytest.mark.slow

FIG11 = "fig11_obstacles"
DT = 0.05
# 2,400 ticks, 2-3 s of wall time in lockstep: long enough to be running still
# when a test acts (the launcher's view of the sim time lags up to 0.25 s).
LONG = {"run.duration_s": 120.0, "leader.waypoints": [[0.0, 0.0], [0.0, 1000.0]]}


def _printed(res: RunResult) -> str:
    out = io.StringIO()
    print_result(res, out)
    return out.getvalue()


def test_robots_cut_off_beyond_the_lease_in_lockstep_are_waited_for_and_rejoin(
    swarm_launch: Callable[..., Launch],
) -> None:
    """Every agent SIGSTOPped for 15 s (their processes live; the router drops
    their sessions at the 10 s lease, as in a network partition). Before, the
    world lost all three robots and ran the rest of the run alone in a second,
    before they were back. Now they stall after STALL_AFTER_MISSES misses, the
    world holds its clock once their tokens go, re-admits them when they are
    back, and the run goes on with them to its end. No fault of the schedule
    cut them off: the run is not reproducible, and fails."""
    launch = swarm_launch(FIG11, logger=False, overrides=LONG)
    assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
    agents = [launch.pids()[f"agent-{rid}"] for rid in (1, 2, 3)]
    for pid in agents:
        os.kill(pid, signal.SIGSTOP)
    try:
        assert launch.wait_until(lambda: False, timeout_s=15.0) is False  # the cut lasts 15 s of wall time
    finally:
        for pid in agents:
            os.kill(pid, signal.SIGCONT)
    res = launch.wait(timeout_s=120)
    s = res.summary
    world = s["parts"]["world"]
    assert res.exit_code == 1, s["failure"]
    assert (s["ticks"], s["end_reason"]) == (2400, "duration_reached")
    assert [e["robot"] for e in s["not_reproducible"]] == [1, 2, 3]
    assert world["dead_robots"] == []
    events = [(e["robot"], e["event"]) for e in s["stalls"]]
    assert sorted(events) == sorted(
        [(r, "stalled") for r in (1, 2, 3)] + [(r, "lost while stalled") for r in (1, 2, 3)]
    )
    stalled_at = sorted(e["tick"] for e in s["stalls"] if e["event"] == "stalled")
    lost_at = {e["tick"] for e in s["stalls"] if e["event"] == "lost while stalled"}
    # Their third miss in a row (one may have answered a tick more before its SIGSTOP);
    # until the lease ends (10 s of wall time) every tick waits its 2 s for them all:
    # a few ticks, no more; then no tick passes until they are back.
    assert stalled_at[-1] - stalled_at[0] <= 1
    assert all(stalled_at[-1] < t <= stalled_at[0] + 6 for t in lost_at), (stalled_at, lost_at)
    assert 3 * STALL_AFTER_MISSES <= s["lockstep_misses"] <= 3 * (STALL_AFTER_MISSES + 6)
    rejoins = sorted((r["robot"], r["cause"]) for r in world["rejoins"])
    assert rejoins == [(r, "lost") for r in (1, 2, 3)]
    (back,) = {r["readmitted_tick"] for r in world["rejoins"]}  # all back on the tick the clock held at:
    assert max(lost_at) <= back <= max(lost_at) + 1  # the one of the last loss, or the next if no tick was left
    assert 1.0 < world["held_for_lost_s"] < LOST_WAIT_S
    assert all(s["processes"][f"agent-{r}"]["exit_code"] == 0 for r in (1, 2, 3))
    print("cut off 15 s: stalls", s["stalls"], "misses", s["lockstep_misses"], "held", world["held_for_lost_s"])


def test_a_logger_killed_outside_the_schedule_cuts_the_recording_at_its_tick(
    swarm_launch: Callable[..., Launch],
) -> None:
    """Before, a logger SIGKILLed from outside left exit 0, recording_cut null, and
    a console that placed the kill by the world's last status, 1-3 s of sim
    time early. Now the run fails, and the summary and the console place the
    kill at the tick the world saw the logger's token go."""
    lines: list[str] = []
    launch = swarm_launch(FIG11, progress=lines.append)
    assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
    before = launch.sim_time()
    os.kill(launch.pids()["logger"], signal.SIGKILL)
    res = launch.wait(timeout_s=240)
    s = res.summary
    seen = s["parts"]["world"]["logger_lost"]
    assert seen["tick"] >= round(before / DT)
    assert seen["time_s"] == pytest.approx(seen["tick"] * DT)
    (exited,) = [e for e in s["events"] if e["event"] == "exited"]
    assert (exited["process"], exited["code"], exited["tick"]) == ("logger", -9, seen["tick"])
    assert exited["sim_time_s"] == seen["time_s"]
    at = f"at sim t={seen['time_s']:.2f} s (tick {seen['tick']})"
    assert res.exit_code == 1
    assert s["ticks"] == 1061  # the run went on to its end
    assert s["failure"] == logger_lost(s["parts"]["world"], s["events"])  # the loss recorded above
    assert s["recording_cut"].startswith(f"the logger was killed by SIGKILL {at}, outside the fault schedule: ")
    printed = _printed(res)
    assert f"event: logger was killed by SIGKILL {at}" in printed
    assert f"RECORDING CUT SHORT: the logger was killed by SIGKILL {at}" in printed
    live = [line for line in lines if line.startswith("[swarm] logger was killed by SIGKILL")]
    assert len(live) == 1
    assert "during the run (the world's last status: sim t=" in live[0]
    assert "[swarm] the run failed: the logger was killed by SIGKILL" in "\n".join(lines)


def test_a_world_killed_after_its_first_tick_is_not_said_to_have_ended_before_it(
    swarm_launch: Callable[..., Launch],
) -> None:
    launch = swarm_launch(FIG11, mode="realtime", overrides={"run.duration_s": 30.0})
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    os.kill(launch.pids()["world"], signal.SIGKILL)
    res = launch.wait(timeout_s=60)
    assert res.exit_code == 1
    seen = res.summary["ticks_seen"]
    assert isinstance(seen, int)
    assert seen >= 20
    printed = _printed(res)
    assert "before its first tick" not in printed, printed
    assert f"no metrics: the world wrote none (the run had reached tick {seen})" in printed
    assert f"recording: {res.recording}\n" in printed  # not "(empty ...)": it holds the ticks until the kill


def test_a_run_folder_deleted_during_a_realtime_run_fails_in_one_line(swarm_launch: Callable[..., Launch]) -> None:
    """Before: exit 0, the recording and logs gone without a word (the world even
    made the folder again for its stats, and the summary went beside them)."""
    lines: list[str] = []
    launch = swarm_launch(FIG11, mode="realtime", overrides={"run.duration_s": 4.0}, progress=lines.append)
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    original = launch.run_dir.stat().st_ino
    while launch.run_dir.exists() and launch.run_dir.stat().st_ino == original:
        shutil.rmtree(launch.run_dir, ignore_errors=True)  # the processes write into it meanwhile
    res = launch.wait(timeout_s=60)
    assert res.exit_code == 1
    said = [line for line in lines if str(launch.run_dir) in line]
    assert said == [
        f"[swarm] the run failed: its folder {launch.run_dir} was deleted during the run: its recording, logs and "
        "stats are lost"
    ]
    assert not (launch.run_dir / "summary.json").exists()
    assert "nothing of the run is kept there" in _printed(res)


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 16 MiB tmpfs: a disk a test can fill."""
    mount = tmp_path / "disk"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16m", "tmpfs", str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (root only): {done.stderr.decode().strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


def _fill(folder: Path) -> None:
    """Write until the disk is full."""
    with contextlib.suppress(OSError), (folder / "filler").open("wb") as f:
        while True:
            f.write(b"\0" * 65536)
            f.flush()


def test_a_full_disk_fails_the_run_naming_the_path_and_leaves_nothing_half_written(
    swarm_launch: Callable[..., Launch], small_disk: Path
) -> None:
    """The disk fills once the run has ticked. Before: stats/*.json.tmp left behind,
    and the console said the run had ended before its first tick. Now one line
    names the file that could not be written, the run fails, and no temporary
    file is left."""
    lines: list[str] = []
    out = small_disk / "run"
    launch = swarm_launch(FIG11, out=out, overrides=LONG, progress=lines.append)
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    _fill(small_disk)
    res = launch.wait(timeout_s=120)
    assert res.exit_code == 1
    said = [line for line in lines if line.startswith("[swarm] the run failed: cannot write")]
    assert said == [f"[swarm] the run failed: cannot write {out / 'summary.json'}: No space left on device"]
    assert sorted(p.name for p in out.rglob("*.tmp")) == []
    printed = _printed(res)
    assert "before its first tick" not in printed, printed


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError(f"no VmRSS for {pid}")


def _given_back(stats: Path) -> int:
    """An agent's memory_given_back in its stats file so far (0 before the first)."""
    try:
        return int(json.loads(stats.read_text()).get("memory_given_back", 0))
    except (OSError, ValueError):
        return 0


def test_memory_a_flood_takes_is_bounded_and_given_back(swarm_launch: Callable[..., Launch]) -> None:
    """Robot 2's login floods its command and telemetry keys with 20,000 payloads
    of 30 kB each (rejected by the world and by agent 2). Before, the world held
    about 60 MB more and agent 2 40 MB more for the rest of the run (Zenoh's
    shared memory of the sender, mapped by each receiver, and the allocator's
    free pages). Now both are within a few MB of where they were once the
    flood has been over for a check period or two."""
    launch = swarm_launch(
        FIG11, logger=False, overrides={"run.duration_s": 600.0, "leader.waypoints": [[0.0, 0.0], [0.0, 2000.0]]}
    )
    assert launch.wait_until(lambda: launch.sim_time() >= 2.0, timeout_s=60)
    pids = {name: launch.pids()[name] for name in ("world", "agent-2")}
    before = {name: _rss_mb(pid) for name, pid in pids.items()}
    k = Keys(launch.run_id)
    payload = b"\0" * 30_000
    with rogue(launch, "agent-2") as sess:
        put_all(sess, [(k.cmd(2), payload), (k.telemetry(2), payload)], rounds=20_000)
    peak = {name: _rss_mb(pid) for name, pid in pids.items()}
    bound = {"world": 20.0, "agent-2": 8.0}  # MB above the start, once given back (measured: 12-15, 0-1)
    settled = launch.wait_until(
        lambda: all(_rss_mb(pid) - before[name] < bound[name] for name, pid in pids.items()),
        timeout_s=4 * FLOOD_CHECK_S + 10.0,
    )
    after = {name: _rss_mb(pid) for name, pid in pids.items()}
    print("flood of 40,000 x 30 kB: RSS MB before", before, "peak", peak, "after", after)
    assert settled, (before, peak, after)
    # The agent gives back in its first look (every FLOOD_CHECK_S) once its inbox is drained:
    # wait for its stats (written every second) to say so, as a loaded machine drains slowly.
    stats = launch.run_dir / "stats" / "agent-2.json"
    assert launch.wait_until(lambda: _given_back(stats) >= 1, timeout_s=4 * FLOOD_CHECK_S + 10.0)
    launch.interrupt()
    res = launch.wait(timeout_s=60)
    parts = res.summary["parts"]
    assert parts["world"]["rejected"] == {"not msgpack": 20_000}
    assert parts["agent-2"]["rejected"] == {"unexpected key": 40_000}
    assert parts["agent-2"]["memory_given_back"] >= 1  # (the world's comes within FLOOD_CHECK_S of its own)
