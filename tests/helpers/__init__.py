"""What the tests share: the repository's paths, our processes, recordings read back."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from formation_swarm.launch.launcher import Launch, RunResult

ROOT = Path(__file__).resolve().parent.parent.parent
SCENARIOS = ROOT / "scenarios"
OUR_MODULES = (
    "formation_swarm.nodes.world.main",
    "formation_swarm.nodes.agent.main",
    "formation_swarm.nodes.logger.main",
    "formation_swarm.nodes.router",
)
RERUN = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")


def rrd_rows(path: Path, static: bool = False) -> dict[str, int]:
    """Rows per entity path in a recording (an absent or empty file has none):
    the rows on its timeline (one per tick and entity), or with ``static``
    its static rows (obstacles, how each robot is drawn)."""
    from rerun.chunk import RrdReader

    rows: dict[str, int] = {}
    if path.exists() and path.stat().st_size > 0:
        for chunk in RrdReader(str(path)).stream():
            if chunk.is_static == static:
                rows[str(chunk.entity_path)] = rows.get(str(chunk.entity_path), 0) + chunk.num_rows
    return rows


def wait_listening(port: int, timeout_s: float) -> None:
    """Return once something accepts connections on loopback ``port``."""
    deadline = time.monotonic() + timeout_s
    while True:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        assert time.monotonic() < deadline, f"nothing listens on port {port}"
        time.sleep(0.05)


def outward_address() -> str | None:
    """This machine's address on its default route (not loopback), if any."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("10.255.255.255", 1))  # no packet is sent: it only picks the route
        except OSError:
            return None
        address = s.getsockname()[0]
    return None if address.startswith("127.") else address


def processes(match: Callable[[str], bool]) -> list[tuple[int, str]]:
    """Live processes whose command line ``match`` accepts (zombies excluded)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (entry / "stat").read_text().split(") ", 1)[1][0]
        except OSError:
            continue
        if state != "Z" and match(cmd):
            found.append((int(entry.name), cmd.strip()))
    return found


def our_processes() -> list[tuple[int, str]]:
    """Live processes running one of our roles."""
    return processes(lambda cmd: any(f"-m {m} " in cmd for m in OUR_MODULES))


def reap(procs: Iterable[subprocess.Popen[Any]], grace_s: float = 5.0) -> None:
    """SIGTERM every process still running, then SIGKILL any not gone within ``grace_s`` in all."""
    procs = list(procs)
    deadline = time.monotonic() + grace_s
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def run_together(
    start: Callable[..., Launch], *runs: tuple[str | Path, Mapping[str, Any]], timeout_s: float = 300.0
) -> list[RunResult]:
    """Runs (scenario, ``swarm_launch``'s keywords) started together, then each
    waited for. Only for lockstep runs without process faults: nothing in them
    depends on the wall clock or on their launcher while they run, and a lockstep
    run's processes wait on each other, so two runs on two cores take little more
    than one."""
    launches = [start(scenario, **kwargs) for scenario, kwargs in runs]
    return [launch.wait(timeout_s=timeout_s) for launch in launches]


class Console:
    """A command started with its console (stdout and stderr) read on a thread:
    ``seen`` is set once a line holding ``marker`` has come."""

    def __init__(self, argv: list[str], marker: str) -> None:
        import subprocess
        import threading

        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        self.seen = threading.Event()
        self._marker = marker
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)
            if self._marker in line:
                self.seen.set()

    def wait(self, timeout_s: float) -> int:
        """The exit code, the process killed and reaped if it outlives ``timeout_s``."""
        try:
            return self.proc.wait(timeout=timeout_s)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
            self._reader.join(timeout=5)

    def close(self) -> None:
        """Kill and reap it if it still runs (after a failed assertion)."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    @property
    def text(self) -> str:
        return "".join(self.lines)
