"""The logger's live outputs: a stream to a viewer (--live) and a served web viewer (--serve-web).

A headless ``rerun --save`` stands in for the viewer: it writes what it
receives to a file, which is then read back like the run's own recording.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import time
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path

from formation_swarm.launcher import Launch, RunResult, free_port
from tests.conftest import RERUN, SCENARIOS, rrd_rows

FIG11 = SCENARIOS / "fig11_obstacles.toml"


def _wait_listening(port: int, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while True:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        assert time.monotonic() < deadline, f"nothing listens on port {port}"
        time.sleep(0.05)


@contextlib.contextmanager
def _saving_viewer(args: list[str], out: Path) -> Iterator[subprocess.Popen[bytes]]:
    """``rerun ARGS --save OUT``, stopped and reaped at the end. ``rerun`` is a
    Python launcher that starts the real binary as its child: the whole
    process group is stopped, or the binary would outlive the test."""
    proc = subprocess.Popen([RERUN, *args, "--save", str(out)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)  # fmt: skip
    try:
        yield proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        deadline = time.monotonic() + 10
        while _group_alive(proc.pid):
            if time.monotonic() > deadline:
                os.killpg(proc.pid, signal.SIGKILL)
                break
            time.sleep(0.05)


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _wait_rows(path: Path, entity: str, n: int, timeout_s: float) -> dict[str, int]:
    """The file's rows once ``entity`` has ``n`` (the viewer writes as it receives)."""
    deadline = time.monotonic() + timeout_s
    while (rows := rrd_rows(path)).get(entity, 0) < n and time.monotonic() < deadline:
        time.sleep(0.2)
    return rows


def test_live_stream_carries_what_the_recording_has(tmp_path: Path, swarm_run: Callable[..., RunResult]) -> None:
    port = free_port()
    live = tmp_path / "live.rrd"
    with _saving_viewer(["--port", str(port)], live):
        _wait_listening(port, timeout_s=30)
        res = swarm_run(FIG11, live=f"rerun+http://127.0.0.1:{port}/proxy", overrides={"run.duration_s": 6.0})
        assert res.exit_code == 0
        ticks = res.summary["ticks"]
        got = _wait_rows(live, "/robots/r3/ekf/target", ticks, timeout_s=20)
    recorded = rrd_rows(res.recording)
    for entity in ("/robots/r1/trajectory", "/robots/r2/trajectory", "/robots/r3/trajectory",
                   "/robots/r2/ekf/target", "/robots/r3/ekf/target", "/robots/r2/fis/v_n"):  # fmt: skip
        assert recorded[entity] == ticks, entity
        assert got.get(entity, 0) == ticks, (entity, got.get(entity, 0), ticks)


def test_served_web_viewer_answers_and_streams(tmp_path: Path, swarm_launch: Callable[..., Launch]) -> None:
    grpc_port, web_port, viewer_port = free_port(), free_port(), free_port()
    launch = swarm_launch(FIG11, mode="realtime", serve_web=True, web_ports=(grpc_port, web_port),
                          overrides={"run.duration_s": 4.0})  # fmt: skip
    log = launch.run_dir / "logs" / "logger.log"
    assert launch.wait_until(lambda: log.exists() and "data at" in log.read_text(), timeout_s=60)
    with urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=10) as page:
        assert page.status == 200
        assert b"<html" in page.read(4096).lower()
    web = tmp_path / "web.rrd"
    with _saving_viewer([f"rerun+http://127.0.0.1:{grpc_port}/proxy", "--port", str(viewer_port)], web):
        res = launch.wait(timeout_s=120)
        assert res.exit_code == 0
        ticks = res.summary["ticks"]
        got = _wait_rows(web, "/robots/r1/trajectory", ticks, timeout_s=10)
    # The server keeps what was logged before the viewer connected, and the
    # logger flushes its sinks before it exits.
    for entity in ("/robots/r1/trajectory", "/robots/r3/ekf/target"):
        assert got.get(entity, 0) == ticks, (entity, got.get(entity, 0), ticks)
