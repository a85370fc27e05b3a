"""Endings told as they happened: a world killed from outside is named in
the run's failure, and a Ctrl-C during start-up leaves no child of the
``swarm`` command behind (its fork server and resource tracker included).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from formation_swarm.launch.console import print_result
from formation_swarm.launch.launcher import Launch

pytestmark = pytest.mark.slow

FIG11 = "fig11_obstacles"
SWARM = Path(sys.executable).parent / "swarm"
COMMAND = [str(SWARM)] if SWARM.exists() else [sys.executable, "-m", "formation_swarm.cli"]
GONE_WITHIN_S = 3.0  # after the command's exit, for every process it started
EXIT_WITHIN_S = 60.0
# A fork server slow to import the roles' modules, as on a loaded machine
# (seen: 10-20 s): it sleeps in its site customisation, before its main loop.
SLOW_SERVER = """\
import os, time
if b"multiprocessing.forkserver" in open("/proc/self/cmdline", "rb").read():
    time.sleep(float(os.environ.get("SLOW_FORK_SERVER_S", "0")))
"""


def test_a_world_killed_from_outside_is_named_in_the_failure(swarm_launch: Callable[..., Launch]) -> None:
    """Before: exit 1 with ``failure`` null. Now the failure names the world,
    how it ended and the last sim time the launcher had from it."""
    launch = swarm_launch(FIG11, logger=False, mode="realtime", overrides={"run.duration_s": 30.0})
    assert launch.wait_until(lambda: launch.sim_time() >= 1.0, timeout_s=60)
    os.kill(launch.pids()["world"], signal.SIGKILL)
    res = launch.wait(timeout_s=60)
    s = res.summary
    (exited,) = [e for e in s["events"] if e["event"] == "exited"]
    assert (res.exit_code, s["end_reason"], exited["process"], exited["code"]) == (1, "role_failed", "world", -9)
    t = exited["sim_time_s"]
    assert t >= 1.0
    assert re.findall(r"world|SIG\w+|t=-?[\d.]+", s["failure"]) == ["world", "SIGKILL", f"t={t:.2f}"]
    out = io.StringIO()
    print_result(res, out)
    assert f"  failed: {s['failure']}\n" in out.getvalue()


def _tree(root: int) -> set[int]:
    """Every live process descended from ``root`` (by the parent ids of /proc)."""
    parents: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError):
                state, ppid = (entry / "stat").read_text().rsplit(") ", 1)[1].split()[:2]
                if state != "Z":
                    parents.setdefault(int(ppid), []).append(int(entry.name))
    found, todo = set(), [root]
    while todo:
        for child in parents.get(todo.pop(), []):
            found.add(child)
            todo.append(child)
    return found


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(") ", 1)[1][0] != "Z"
    except OSError:
        return False


def _command_line(pid: int) -> str:
    with contextlib.suppress(OSError):
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    return "(gone)"


def test_ctrl_c_during_start_up_leaves_no_child_behind(tmp_path: Path) -> None:
    """SIGINT to ``swarm run``'s process group while its fork server still
    imports the roles' modules (made slow here, 20 s, as a loaded machine
    makes it). Before: "every process stopped" was printed and the command
    exited, and the fork server and the resource tracker lived on until the
    server's imports were done. Now none of its children outlives it by
    more than GONE_WITHIN_S."""
    (tmp_path / "site").mkdir()
    (tmp_path / "site" / "sitecustomize.py").write_text(SLOW_SERVER)
    path = os.pathsep.join(p for p in (str(tmp_path / "site"), os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "PYTHONPATH": path, "SLOW_FORK_SERVER_S": "20"}
    proc = subprocess.Popen(
        [*COMMAND, "run", FIG11, "--out", str(tmp_path / "run"), "--no-logger"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
        env=env,
    )
    seen: set[int] = set()
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()
        assert first.startswith("[swarm] run "), first
        deadline = time.monotonic() + EXIT_WITHIN_S
        # Once the fork server is there (importing, for 20 s): the start waits for it.
        while not any("multiprocessing.forkserver" in _command_line(p) for p in seen):
            assert time.monotonic() < deadline, f"no fork server started: {[_command_line(p) for p in seen]}"
            seen |= _tree(proc.pid)
            time.sleep(0.01)
        os.killpg(proc.pid, signal.SIGINT)
        while proc.poll() is None and time.monotonic() < deadline:
            seen |= _tree(proc.pid)
            time.sleep(0.01)
        exited_at = time.monotonic()
        code = proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        # Its children hold its stdout too: the rest of it is read once they are gone.
        while [p for p in seen if _alive(p)] and time.monotonic() < exited_at + GONE_WITHIN_S:
            time.sleep(0.02)
        left = {p: _command_line(p) for p in seen if _alive(p)}
        for pid in left:  # reaped here, so that a failure leaves nothing behind either
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        rest = proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 130, rest
    assert "[swarm] interrupted while starting; every process stopped" in rest, rest
    assert left == {}, f"{len(seen)} children seen; alive {GONE_WITHIN_S:g} s after the exit"
