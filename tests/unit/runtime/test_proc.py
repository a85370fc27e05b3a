"""swarm.proc: the JsonWriter (the newest snapshot reaches the file, off the
caller's thread) and the real-time class of the real-time world."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from formation_swarm.runtime import proc


def test_the_writer_writes_the_newest_snapshot_and_a_copy_of_it(tmp_path: Path) -> None:
    path = tmp_path / "stats" / "agent-2.json"
    w = proc.JsonWriter(str(path))
    holds = [[1, 2]]
    w.offer({"answered": 1, "holds": holds})
    holds.append([5, 9])  # changed by the caller after the offer: the file keeps what was offered
    w.offer({"answered": 2, "holds": holds[:1], "nan": float("nan")})
    w.close()
    assert json.loads(path.read_text()) == {"answered": 2, "holds": [[1, 2]], "nan": None}
    w = proc.JsonWriter(str(path))
    w.offer({"answered": 3})
    w.close({"answered": 4})  # the last, written after any snapshot offered before it
    assert json.loads(path.read_text()) == {"answered": 4}
    assert not path.with_suffix(".json.tmp").exists()
    assert w.errors == 0


def test_a_slow_write_does_not_hold_the_caller_and_later_offers_replace_waiting_ones(
    tmp_path: Path, monkeypatch: object
) -> None:
    path = tmp_path / "s.json"
    release = threading.Event()
    written: list[int] = []
    real = proc.write_json

    def slow(p: str | None, data: dict) -> None:
        release.wait(10.0)
        written.append(data["n"])
        real(p, data)

    monkeypatch.setattr(proc, "write_json", slow)  # type: ignore[attr-defined]
    w = proc.JsonWriter(str(path))
    for n in range(50):  # none of these waits for the disk
        w.offer({"n": n})
    release.set()
    w.close()
    assert written[-1] == 49
    assert len(written) <= 2  # the first, if the thread took it before the rest came, and the newest
    assert json.loads(path.read_text()) == {"n": 49}


def test_an_unwritable_path_is_counted_not_raised(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    w = proc.JsonWriter(str(blocker / "sub" / "s.json"))  # a file where a folder should be
    w.offer({"n": 1})
    w.close()
    assert w.errors == 1


def test_no_path_writes_nothing_and_starts_no_thread() -> None:
    w = proc.JsonWriter(None)
    w.offer({"n": 1})
    w.close()
    assert w.errors == 0


def _in_child(code: str, as_nobody: bool = False) -> subprocess.CompletedProcess[str]:
    """Run ``code`` (with swarm.proc imported) in a fresh process, as user nobody if asked."""
    prelude = "import os\nfrom formation_swarm.runtime import proc\n"
    if as_nobody:
        prelude += "os.setgid(65534)\nos.setuid(65534)\n"
    return subprocess.run([sys.executable, "-c", prelude + code], capture_output=True, text=True, check=True)


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root, to have the right to a real-time class and to drop it")
def test_the_real_time_class_is_taken_by_the_thread_and_the_threads_it_starts() -> None:
    out = _in_child(
        "import threading\n"
        "print(proc.realtime_priority(10))\n"
        "seen = []\n"
        "t = threading.Thread(target=lambda: seen.append(os.sched_getscheduler(0)))\n"
        "t.start(); t.join()\n"
        "print(os.sched_getscheduler(0) == os.SCHED_RR, seen == [os.SCHED_RR], os.sched_getparam(0).sched_priority)\n"
    ).stdout.splitlines()
    said, seen = out
    assert said.startswith("real-time")
    assert "SCHED_RR 10" in said  # the class and the priority taken
    assert seen.split() == ["True", "True", "10"]  # this thread's class, its child's, the priority


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root, to become a user without the right to a real-time class")
def test_without_the_right_the_process_stays_normal_and_says_why() -> None:
    out = _in_child("print(proc.realtime_priority(10)); print(os.sched_getscheduler(0) == os.SCHED_OTHER)", True)
    said, normal = out.stdout.splitlines()
    assert said.startswith("normal (real-time priority 10 refused: Operation not permitted; it needs root or ")
    assert "ulimit -r 10" in said
    assert normal == "True"


def test_priority_zero_is_the_normal_class_and_out_of_range_is_refused() -> None:
    assert proc.realtime_priority(0) == "normal"
    with pytest.raises(ValueError, match=r"\[0, 99\], got 100"):
        proc.realtime_priority(100)


SENT = 2_000_000  # far more than the reader's buffer holds


def _writer(port: int, wait: bool) -> None:
    """A child process: write SENT bytes, maybe wait until they are taken, and
    exit with input unread (the reader's greeting): Linux resets the connection."""
    import socket

    try:
        with socket.create_connection(("127.0.0.1", port)) as s:
            s.sendall(b"x" * SENT)  # returns once our kernel holds it all, not once it left
            if wait:
                proc.wait_sent(20.0)
            os._exit(0)  # the unread greeting makes this a reset
    finally:
        os._exit(1)


@pytest.mark.parametrize("wait", [False, True])
def test_what_a_process_wrote_survives_its_exit_only_once_the_peer_took_it(wait: bool) -> None:
    """proc.wait_sent: without it a process that exits with input unread (a
    reset) throws away what it wrote and the slow reader had not yet taken."""
    import multiprocessing
    import socket
    import time

    with socket.socket() as srv:
        srv.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8192)  # a slow reader with a small buffer
        srv.bind(("127.0.0.1", 0))
        srv.listen()
        child = multiprocessing.get_context("fork").Process(target=_writer, args=(srv.getsockname()[1], wait))
        child.start()
        conn, _ = srv.accept()
        with conn:
            conn.sendall(b"hello")  # never read by the writer
            got, deadline = 0, time.monotonic() + 60
            try:
                while time.monotonic() < deadline:
                    chunk = conn.recv(16384)
                    if not chunk:
                        break
                    got += len(chunk)
                    time.sleep(0.0005)  # slower than the writer
            except ConnectionResetError:
                pass
        child.join(30)
    assert child.exitcode == 0
    if wait:
        assert got == SENT
    else:
        assert got < SENT  # the reset threw the rest away


def test_a_json_write_that_fails_leaves_no_temporary_file(tmp_path: Path) -> None:
    target = tmp_path / "stats.json"
    target.mkdir()  # the rename onto it fails, as a full disk fails the write
    with pytest.raises(IsADirectoryError):
        proc.write_json(str(target), {"a": 1})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stats.json"]
