"""What ``swarm host`` does for runs: it answers a launcher's requests
(protocol.hostmsg: info, start, signal, poll, collect, end) and starts,
signals, watches and ends the agents of each run, forked from the spawner
(formation_swarm.runtime.spawner) as ``swarm run`` forks them, each with the
login the launcher sent for it. A start repeated while its agent runs (a
retry) gets the first one's answer. The process around it: formation_swarm.nodes.host.main.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from formation_swarm.common.version import __version__
from formation_swarm.protocol import acl, hostmsg, trust
from formation_swarm.protocol.codec import DecodeError, Rejections
from formation_swarm.protocol.hostmsg import HostReply, HostRequest
from formation_swarm.protocol.keys import HostKeys, Keys
from formation_swarm.runtime.children import Child

STOP_GRACE_S = 3.0  # SIGTERM -> SIGKILL
# A client whose router vanished is told its tokens went only later (seconds,
# measured with Zenoh 1.10). The launcher of a run on hosts is its router, so
# the host also looks this often at the router it is connected to, and takes
# that router gone (or another in its place) twice in a row for the
# launcher's end. A local look: no query that a loaded machine could delay.
CHECK_PERIOD_S = 0.5
ROUTER_CHECK_S = 1.0  # how often a host looks whether it still has a router (said when it goes and comes back)
LAUNCHER_WAIT_S = 60.0
ACTIONS = {"kill": signal.SIGKILL, "freeze": signal.SIGSTOP, "thaw": signal.SIGCONT, "term": signal.SIGTERM}
AGENT = "formation_swarm.nodes.agent.main"


def free_memory_mb() -> int:
    with contextlib.suppress(OSError, ValueError, IndexError):
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) // 1024
    return 0


@dataclass
class HostRun:
    """The agents this host runs for one run, and what it knows of its launcher."""

    run: str
    folder: Path
    started_at: float
    children: dict[str, Child] = field(default_factory=dict)
    requests: dict[str, tuple[Any, ...]] = field(default_factory=dict)  # per child, the start that made it
    frozen: set[str] = field(default_factory=set)
    launcher: str = "unseen"  # unseen -> present -> gone (set by the liveliness callback)
    watcher: Any = None
    checked_at: float = 0.0
    routers: frozenset[str] = frozenset()  # the router(s) the host was connected to when the launcher came
    misses: int = 0  # looks in a row that found none of them


class Host:
    """One host's runs: the requests it answers and the agents it runs for each."""

    def __init__(
        self,
        sess: zenoh.Session,
        name: str,
        *,
        robots: tuple[int, ...] | None,
        connect: list[str],
        settings: dict[str, Any],
        workdir: Path,
        launcher_wait_s: float = LAUNCHER_WAIT_S,
    ) -> None:
        self.session = sess
        self.name = name
        self.keys = HostKeys(name)
        self.robots = robots
        self.connect = connect
        # What an agent's login keeps of the host's settings: all but the host's own login (TLS CA, say).
        self.agent_settings = {k: v for k, v in settings.items() if k != "transport/auth/usrpwd"}
        self.workdir = workdir
        self.launcher_wait_s = launcher_wait_s
        self.runs: dict[str, HostRun] = {}
        self.rejections = Rejections()
        self.router_up = True  # connected when the host starts serving
        self.router_checked_at = time.monotonic()

    def say(self, line: str) -> None:
        print(f"host {self.name}: {line}", flush=True)

    # -- requests -----------------------------------------------------------------
    def answer(self, query: zenoh.Query) -> None:
        payload = query.payload.to_bytes() if query.payload is not None else b""
        try:
            reply = self.handle(payload)
        except (OSError, ValueError) as exc:
            reply = self.refuse(f"{type(exc).__name__}: {exc}")
        query.reply(query.key_expr, reply.to_bytes())

    def refuse(self, why: str) -> HostReply:
        return HostReply(
            ok=False, version=__version__, host=self.name, error=why[: hostmsg.MAX_TEXT], time_unix=time.time()
        )

    def handle(self, payload: bytes) -> HostReply:
        try:
            req = HostRequest.from_bytes(payload)
        except DecodeError as exc:
            self.rejections.reject(exc.reason)
            return self.refuse(f"bad request: {exc}")
        if req.version != __version__:
            self.rejections.reject("other version")
            return self.refuse(
                f"host {self.name} runs formation_swarm {__version__}, the launcher {req.version}: "
                "install the same version on every machine of a run"
            )
        ok = {"ok": True, "version": __version__, "host": self.name, "time_unix": time.time()}
        if req.op == "info":
            running = sum(c.poll() is None for r in self.runs.values() for c in r.children.values())
            return HostReply(
                **ok,
                hostname=socket.gethostname()[:256],
                cores=os.cpu_count() or 0,
                free_mem_mb=free_memory_mb(),
                robots=self.robots,
                running=running,
            )
        if req.op == "start":
            return self.start(req, ok)
        return self.on_run(req, ok)

    def on_run(self, req: HostRequest, ok: dict[str, Any]) -> HostReply:
        """A request about a run's agents: end, poll, signal or collect."""
        run = self.runs.get(req.run)
        if req.op == "end":
            if run is not None:
                self.end(run, "the launcher ended it")
            return HostReply(**ok)
        if run is None:
            return self.refuse(f"host {self.name} runs nothing of run {req.run}")
        if req.op == "poll":
            procs = tuple((n, c.pid or 0, _code(c.poll())) for n, c in run.children.items())
            return HostReply(**ok, processes=procs)
        child = run.children.get(req.process)
        if child is None:
            return self.refuse(f"host {self.name} has no {req.process} in run {req.run}")
        if req.op == "signal":
            if req.action == "term" and req.process in run.frozen:
                child.signal(signal.SIGCONT)
            child.signal(ACTIONS[req.action])
            (run.frozen.add if req.action == "freeze" else run.frozen.discard)(req.process)
            return HostReply(**ok)
        return self.collect(run, child, ok)  # collect

    def start(self, req: HostRequest, ok: dict[str, Any]) -> HostReply:
        robot = hostmsg.process_robot(req.process)
        if robot is None:  # the decoder refuses such a name already
            return self.refuse(f"{req.process!r} is not agent-N")
        if self.robots is not None and robot not in self.robots:
            return self.refuse(f"host {self.name} may run robots {', '.join(map(str, self.robots))}, not {robot}")
        if req.user != acl.agent_user(robot):
            return self.refuse(f"the login of {req.process} must be {acl.agent_user(robot)}, got {req.user!r}")
        run = self.runs.get(req.run)
        if run is None:
            run = self.open_run(req.run)
        old = run.children.get(req.process)
        if old is not None and old.poll() is None:
            if run.requests.get(req.process) == _start_identity(req):
                # The same start again: a launcher's retry whose first reply was late or lost.
                return HostReply(**ok, pid=old.pid)
            return self.refuse(f"{req.process} of run {req.run} already runs here (pid {old.pid})")
        scenario = run.folder / "scenario.toml"
        write_whole(scenario, req.scenario)
        secrets = run.folder / "secrets"
        secrets.mkdir(mode=0o700, exist_ok=True)
        auth = secrets / f"{req.process}.json"
        cred = trust.Credential(req.user, req.password)
        settings = {**self.agent_settings, **trust.client_settings(cred)}
        trust._write_private(auth, json.dumps(settings))
        argv = [
            sys.executable,
            "-m",
            AGENT,
            "--id",
            str(robot),
            "--scenario",
            str(scenario),
            "--run",
            req.run,
            "--stats",
            str(run.folder / "stats" / f"{req.process}.json"),
            *(a for ep in self.connect for a in ("--connect", ep)),
            "--world-grace",
            f"{req.world_grace_s:g}",
            "--auth",
            str(auth),
            *(["--lockstep"] if req.lockstep else []),
        ]
        child = Child(req.process, argv, run.folder / "logs" / f"{req.process}.log")
        run.children[req.process] = child
        run.requests[req.process] = _start_identity(req)
        child.start()
        self.say(f"run {req.run}: started {req.process} (pid {child.pid})")
        return HostReply(**ok, pid=child.pid)

    def open_run(self, run_id: str) -> HostRun:
        folder = self.workdir / run_id
        for sub in ("logs", "stats"):
            (folder / sub).mkdir(parents=True, exist_ok=True)
        run = HostRun(run_id, folder, time.monotonic())

        def on_token(sample: zenoh.Sample) -> None:  # a Zenoh thread: only a state change
            run.launcher = "present" if sample.kind == zenoh.SampleKind.PUT else "gone"

        run.watcher = self.session.liveliness().declare_subscriber(
            Keys(run_id).alive("launcher", 0), on_token, history=True
        )
        self.runs[run_id] = run
        return run

    def collect(self, run: HostRun, child: Child, ok: dict[str, Any]) -> HostReply:
        log = ""
        with contextlib.suppress(OSError):
            log = hostmsg.tail_bytes(child.log_path.read_text(errors="replace"), hostmsg.MAX_LOG_BYTES - 64)
        stats, error = "", ""
        path = run.folder / "stats" / f"{child.name}.json"
        with contextlib.suppress(OSError):
            stats = path.read_text()
        if len(stats.encode()) > hostmsg.MAX_STATS_BYTES:
            stats, error = "", f"{path} is above {hostmsg.MAX_STATS_BYTES} bytes: left on host {self.name}"
        return HostReply(**ok, code=_code(child.poll()), log=log, stats=stats, error=error, pid=child.pid)

    # -- runs ---------------------------------------------------------------------
    def end(self, run: HostRun, why: str) -> None:
        """Stop every agent of ``run`` (SIGTERM, SIGKILL after STOP_GRACE_S) and reap them."""
        for name in run.frozen:
            run.children[name].signal(signal.SIGCONT)
        live = [c for c in run.children.values() if c.poll() is None]
        for c in live:
            c.signal(signal.SIGTERM)
        deadline = time.monotonic() + STOP_GRACE_S
        while time.monotonic() < deadline and any(c.poll() is None for c in live):
            time.sleep(0.02)
        for c in run.children.values():
            if c.poll() is None:
                c.signal(signal.SIGKILL)
            if c.proc is not None:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    c.proc.wait(timeout=5.0)
            c.close()
        if run.watcher is not None:
            run.watcher.undeclare()
        shutil.rmtree(run.folder / "secrets", ignore_errors=True)
        del self.runs[run.run]
        stopped = f", stopped {len(live)} running agent(s)" if live else ""
        self.say(f"run {run.run} ended ({why}){stopped}; logs in {run.folder / 'logs'}")

    def watch(self) -> None:
        """Say when the router goes and comes back; end the runs whose launcher left, or never came."""
        now = time.monotonic()
        if now - self.router_checked_at > ROUTER_CHECK_S:
            self.router_checked_at = now
            up = bool(list(self.session.info.routers_zid()))
            if up != self.router_up:
                self.router_up = up
                where = ", ".join(self.connect) or "its router"
                self.say(
                    f"connected again to a router at {where}"
                    if up
                    else f"lost its router at {where}; retrying (runs cannot reach this host meanwhile; "
                    "the router of swarm run --hosts, its launcher, goes when its run ends)"
                )
        for run in list(self.runs.values()):
            if run.launcher == "gone":
                self.end(run, "its launcher's token went: the launcher died or its machine left")
            elif run.launcher == "unseen" and now - run.started_at > self.launcher_wait_s:
                self.end(run, f"no launcher of it appeared within {self.launcher_wait_s:g} s")
            elif run.launcher == "present" and now - run.checked_at > CHECK_PERIOD_S:
                run.checked_at = now
                routers = frozenset(str(z) for z in self.session.info.routers_zid())
                if not run.routers:
                    run.routers = routers
                run.misses = 0 if routers & run.routers else run.misses + 1
                if run.misses >= 2:
                    run.launcher = "gone"
            else:
                for c in run.children.values():
                    c.poll()


def write_whole(path: Path, text: str) -> None:
    """``text`` in ``path``, put in place at once: every start of a run writes
    its scenario, which the run's agents started before read as they start,
    and one that read it half written exited with code 2 (a scenario that
    is no TOML, or misses keys)."""
    part = path.with_name(f".{path.name}.part")
    part.write_text(text)
    os.replace(part, path)


def _start_identity(req: HostRequest) -> tuple[Any, ...]:
    """What makes two start requests of one run's process the same start
    (not its send time: a retry is sent later)."""
    return (req.user, req.password, req.scenario, req.world_grace_s, req.lockstep)


def _code(code: int | None) -> int | None:
    return None if code is None else max(-255, min(255, code))
