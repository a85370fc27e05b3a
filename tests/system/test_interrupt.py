"""Ctrl-C at any moment of ``swarm run``: one line, exit code 130, no
traceback, no process left (formation_swarm.cli.interrupts)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.helpers import processes

pytestmark = pytest.mark.slow

SWARM = Path(sys.executable).parent / "swarm"
COMMAND = [str(SWARM)] if SWARM.exists() else [sys.executable, "-m", "formation_swarm.cli"]
SCENARIO = "fig7_turn_vn_dynamic"
MOMENTS_S = [2.0 * i / 19 for i in range(20)]  # after its code starts: importing, preparing, starting, running
EXIT_WITHIN_S = 60.0
GONE_WITHIN_S = 30.0  # a fork server still importing the roles' modules leaves once it is done


@dataclass
class Console:
    """What a command wrote, each line with the time it was read."""

    lines: list[tuple[float, str, str]] = field(default_factory=list)  # (time, stream, line)

    def read(self, stream: str, pipe: object) -> None:
        for line in pipe:  # type: ignore[attr-defined]
            self.lines.append((time.monotonic(), stream, line.rstrip("\n")))

    def text(self, stream: str) -> str:
        return "\n".join(line for _, s, line in self.lines if s == stream)


def _children(pid: int) -> list[int]:
    """The live processes whose parent is ``pid`` (the fork server, the resource tracker)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError):
                state, ppid = (entry / "stat").read_text().rsplit(") ", 1)[1].split()[:2]
                if int(ppid) == pid and state != "Z":
                    found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        return (Path(f"/proc/{pid}") / "stat").read_text().rsplit(") ", 1)[1][0] != "Z"
    except OSError:
        return False


def _command_started(pid: int) -> bool:
    """The command's own code runs: its first act is to hold SIGINT back (SigBlk).
    Before, Python starts (site, .pth files: on a loaded machine 0.1 s and
    more), and a SIGINT then ends in Python's own traceback: none of ours.
    Before that again, the child of Popen has every signal blocked until it
    execs, and has no process group of its own yet (a SIGINT to its group
    would go nowhere): only the exec'd command counts."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        exec_done = SCENARIO.encode() in Path(f"/proc/{pid}/cmdline").read_bytes() and os.getpgid(pid) == pid
    except OSError:
        return True  # gone already
    if not exec_done:
        return False
    blocked = next((line.split()[1] for line in status.splitlines() if line.startswith("SigBlk:")), "0")
    return bool(int(blocked, 16) & (1 << (signal.SIGINT - 1)))


def _interrupt_at(
    moment_s: float, out: Path, ignore_sigint: bool = False
) -> tuple[int | None, Console, float, list[int]]:
    """Start ``swarm run``, send its process group a SIGINT (a terminal's Ctrl-C)
    ``moment_s`` after its code started; its exit code (None: it had ended
    before), its console, when the signal went, its children then."""
    console = Console()
    proc = subprocess.Popen(
        [*COMMAND, "run", SCENARIO, "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=(lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if ignore_sigint else None,  # noqa: PLW1509
    )
    deadline = time.monotonic() + EXIT_WITHIN_S
    while not _command_started(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.001)
    started = time.monotonic()
    readers = [
        threading.Thread(target=console.read, args=(name, pipe), daemon=True)
        for name, pipe in (("out", proc.stdout), ("err", proc.stderr))
    ]
    for reader in readers:
        reader.start()
    time.sleep(max(0.0, started + moment_s - time.monotonic()))  # the moment is the test's subject
    children = _children(proc.pid)
    sent = time.monotonic()
    ended_before = proc.poll() is not None
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGINT)
    try:
        code = proc.wait(timeout=EXIT_WITHIN_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    for reader in readers:
        reader.join(timeout=5)
    return (None if ended_before else code), console, sent, children


def test_ctrl_c_at_any_moment_of_swarm_run(tmp_path: Path) -> None:
    hit = 0
    for i, moment_s in enumerate(MOMENTS_S):
        out = tmp_path / f"run-{i}"
        code, console, sent, children = _interrupt_at(moment_s, out)
        if code is None:  # the run was over before this moment (a fast machine): not a moment of it
            continue
        hit += 1
        where = f"SIGINT {moment_s:.2f} s after the start:\n{console.text('out')}\n{console.text('err')}"
        assert code == 130, where
        assert "Traceback" not in console.text("err"), where
        assert "Fatal Python error" not in console.text("err"), where
        after = [line for t, _, line in console.lines if t >= sent]
        assert len(after) <= 2, where  # one line says so (and one read just after it was written)

        def left(out: Path = out, children: list[int] = children) -> list[str]:
            roles = [cmd for _, cmd in processes(lambda cmd: str(out) in cmd)]
            return roles + [f"child {pid}" for pid in children if _alive(pid)]

        deadline = time.monotonic() + GONE_WITHIN_S
        while left() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert left() == [], where
    assert hit >= len(MOMENTS_S) // 2, f"only {hit} of the moments came while swarm run ran"


def test_ctrl_c_at_the_start_of_a_run_started_with_sigint_ignored(tmp_path: Path) -> None:
    """A background job of a shell, or a child of a parent that ignores SIGINT,
    starts with it ignored: swarm run still takes a Ctrl-C that comes while
    its first modules load, as it does later on."""
    code, console, _sent, _children = _interrupt_at(0.0, tmp_path / "run", ignore_sigint=True)
    assert code == 130, console.text("out") + console.text("err")
    assert [line for _, s, line in console.lines if s == "err"] == ["interrupted"]
