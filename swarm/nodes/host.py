"""``swarm host``: one per machine that runs agents for runs started elsewhere.

    swarm host --connect tcp/ROUTER:7447 [--name NAME] [--robots 2,3] [--auth host-NAME.json]

A Zenoh client that holds the liveliness token ``swarmhost/NAME/alive`` and
answers the requests of protocol.hostmsg on ``swarmhost/NAME/ctl``: who it is
(host name, cores, free memory, package version, the robots it may run), and
start, signal, poll, collect (the log tail and stats of an agent) and end the
agents of a run. Agents are forked from the spawner (formation_swarm.runtime.spawner)
as ``swarm run`` forks them, each with the login the launcher sent for it, and
connect where the host does.

It outlives runs: its session retries the router for as long as it runs (the
router of a ``swarm run --hosts`` is that run's world), and it is let in by
each run's router with its own lasting login (``swarm secure --hosts``).

A run's agents are stopped (SIGTERM, then SIGKILL) when the launcher asks,
when the launcher's token goes (the launcher died or its machine left), when
that token has not come within ``--launcher-wait`` s of the run's first agent,
and when the host itself stops (SIGINT/SIGTERM). Requests from another package
version are refused, saying which.
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
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from formation_swarm.common.version import __version__
from formation_swarm.protocol import hostmsg, session, trust
from formation_swarm.protocol.codec import DecodeError, Rejections
from formation_swarm.protocol.hostmsg import HostReply, HostRequest
from formation_swarm.protocol.keys import HostKeys, Keys, check_host_name
from formation_swarm.runtime import cliargs, spawner
from formation_swarm.runtime.children import Child
from formation_swarm.runtime.proc import SIGNAL_CHECK_S, StopEvent, install_stop_handlers

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
AGENT = "formation_swarm.nodes.agent"

DESCRIPTION = """\
Serve this machine to runs started elsewhere: connect to the router, announce
this host (a liveliness token and a queryable: its name, cores, free memory,
package version, the robots it may run) and start, watch and stop agents when
a launcher (swarm run --hosts) asks. It runs until SIGINT or SIGTERM, and
stops a run's agents when that run's launcher goes away."""
EPILOG = """\
examples:
  swarm host --connect tcp/192.168.1.10:7447 --name b --auth secure/host-b.json
  swarm host --connect tls/192.168.1.10:7447 --name c --robots 3,4 --auth host-c.json

exit codes: 0 stopped by SIGINT or SIGTERM; 1 the session could not be opened;
2 bad flags or credentials file."""


def default_name() -> str:
    """This machine's name as a host name (lowercase, letters, digits, '-')."""
    raw = socket.gethostname().split(".")[0].lower()
    name = "".join(ch if ch.isalnum() or ch == "-" else "-" for ch in raw).strip("-")[:27]
    return name if name and name[0].isalpha() else f"h{name}"[:27]


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
    frozen: set[str] = field(default_factory=set)
    launcher: str = "unseen"  # unseen -> present -> gone (set by the liveliness callback)
    watcher: Any = None
    checked_at: float = 0.0
    routers: frozenset[str] = frozenset()  # the router(s) the host was connected to when the launcher came
    misses: int = 0  # looks in a row that found none of them


class Host:
    def __init__(
        self,
        sess: zenoh.Session,
        name: str,
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
        if req.user != trust.agent_user(robot):
            return self.refuse(f"the login of {req.process} must be {trust.agent_user(robot)}, got {req.user!r}")
        run = self.runs.get(req.run)
        if run is None:
            run = self.open_run(req.run)
        old = run.children.get(req.process)
        if old is not None and old.poll() is None:
            return self.refuse(f"{req.process} of run {req.run} already runs here (pid {old.pid})")
        scenario = run.folder / "scenario.toml"
        scenario.write_text(req.scenario)
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
                    else f"lost its router at {where}; retrying (runs cannot reach this host meanwhile)"
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


def _code(code: int | None) -> int | None:
    return None if code is None else max(-255, min(255, code))


def _robot_ids(text: str) -> tuple[int, ...]:
    try:
        ids = tuple(sorted({int(p) for p in text.split(",") if p.strip()}))
    except ValueError:
        ids = ()
    if not ids or ids[0] < 1:
        raise ValueError(f"--robots must be robot ids separated by commas, e.g. 2,3, got {text!r}")
    return ids


def _own_workdir(workdir: Path) -> Any:
    """Lock ``workdir`` for this host process (an open file holding an
    exclusive flock, released when the process ends, however it ends);
    ValueError when another host holds it."""
    import fcntl

    try:
        workdir.mkdir(parents=True, exist_ok=True)
        lock = (workdir / ".lock").open("w")
    except OSError as exc:
        raise ValueError(f"--workdir {workdir}: cannot use it: {exc}") from None
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        raise ValueError(f"--workdir {workdir} is in use by another swarm host: give each its own") from None
    return lock


def _remove_stale_secrets(workdir: Path) -> int:
    """The runs' logins a host killed before its runs' end left behind (a run
    removes its own when it ends); with the workdir locked, none is in use."""
    stale = [d for d in workdir.glob("*/secrets") if d.is_dir()]
    for d in stale:
        shutil.rmtree(d, ignore_errors=True)
    return len(stale)


def _check_login(settings: dict[str, Any], name: str, path: str | None) -> None:
    """A login must be this host's (``host-NAME``): the run's router would let
    another one in only on another host's key, where no launcher asks for it.
    A credentials file without a login is no credentials file."""
    user = trust.login_user(settings)
    if path is not None and user is None:
        raise ValueError(
            f"--auth {path}: holds no login (transport/auth/usrpwd): give host-{name}.json of swarm secure --hosts"
        )
    if user is not None and user != trust.host_user(name):
        whose = f"host {user[5:]}" if str(user).startswith("host-") else f"user {user!r}, not a host's"
        raise ValueError(
            f"--auth {path}: this login is for {whose}, not for host {name} (--name): give the file of "
            f"host {name} (host-{name}.json of swarm secure --hosts) or --name to match"
        )


def open_session(conf: zenoh.Config, stop: StopEvent) -> zenoh.Session | None:
    """``zenoh.open(conf)``, or None once ``stop`` is set first. A client's open
    returns only when a router answered (here it retries for ever) and no signal
    handler runs meanwhile, so it runs on a thread of its own; one left behind
    by a stop is a daemon, ended with the process."""
    done = threading.Event()
    out: list[zenoh.Session] = []
    failed: list[zenoh.ZError] = []

    def run() -> None:
        try:
            out.append(zenoh.open(conf))
        except zenoh.ZError as exc:
            failed.append(exc)
        finally:
            done.set()

    threading.Thread(target=run, name="zenoh-open", daemon=True).start()
    while not stop.is_set() and not done.is_set():
        done.wait(SIGNAL_CHECK_S)
    if failed:
        raise failed[0]
    if out and not stop.is_set():
        return out[0]
    if out:  # opened as the stop came
        out[0].close()
    return None


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(prog="swarm host", description=DESCRIPTION, epilog=EPILOG)
    ap.add_argument(
        "--name",
        default=None,
        metavar="NAME",
        help="this host's name in swarm run --hosts: 1-27 lowercase letters, digits or '-' "
        "(default: the machine's host name)",
    )
    ap.add_argument(
        "--robots", default=None, metavar="IDS", help="the only robot ids this host may run, e.g. 2,3 (default: any)"
    )
    ap.add_argument(
        "--workdir",
        default=None,
        metavar="DIR",
        help="where the agents' scenario, logs and stats go, a folder per run (default: ~/.cache/swarm-host/NAME)",
    )
    ap.add_argument(
        "--launcher-wait",
        type=cliargs.seconds(),
        default=LAUNCHER_WAIT_S,
        metavar="S",
        help=f"stop a run's agents when its launcher's token has not appeared within S s of its "
        f"first agent (default: {LAUNCHER_WAIT_S:g})",
    )
    session.add_arguments(ap)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        name = check_host_name(args.name or default_name())
        robots = _robot_ids(args.robots) if args.robots else None
        settings = trust.read_settings(args.auth) if args.auth else {}
        _check_login(settings, name, args.auth)
        if not args.connect and args.config is None:
            raise ValueError("--connect ENDPOINT: the router to serve runs through (scouting is off)")
        plain = [e for e in args.connect if not e.startswith("tls/") and not session.loopback(e)]
        if settings.get(trust.TLS_ROOT_CA) and plain:  # on this machine, a router's local endpoint may be tcp/
            raise ValueError(
                f"--connect {plain[0]}: this login ({args.auth}) names a CA, for TLS: connect with "
                "tls/ROUTER:PORT, or the agents' passwords would cross the network in clear"
            )
        conf = session.make_config("client", args.connect, (), args.config, settings=settings)
        # The router may come and go (a run's world is one): keep trying, in the background.
        conf.insert_json5("connect/exit_on_failure", "false")
        conf.insert_json5("connect/timeout_ms", "-1")
    except ValueError as exc:
        ap.error(str(exc))
    workdir = Path(args.workdir) if args.workdir else Path.home() / ".cache" / "swarm-host" / name
    try:
        lock = _own_workdir(workdir)  # held while this host runs
    except ValueError as exc:
        print(f"swarm host: {exc}", file=sys.stderr, flush=True)
        return 2
    if stale := _remove_stale_secrets(workdir):
        print(
            f"host {name}: removed the logins of {stale} run(s) a previous host process left in {workdir}", flush=True
        )
    stop = install_stop_handlers()
    spawner.warm()  # the agents' modules imported once, before any launcher waits for a start
    where = ", ".join(args.connect) or args.config
    # A router that refuses this host's login looks, from here, like no router: say so once.
    login = "" if not args.auth else "; a router that refuses this host's login (--auth) looks the same from here"
    print(f"host {name}: waiting for a router at {where} (retrying{login}); stop it with Ctrl-C or SIGTERM", flush=True)
    try:
        sess = open_session(conf, stop)
    except zenoh.ZError as exc:
        print(f"host {name}: cannot open a Zenoh session: {session.zenoh_reason(exc)}", file=sys.stderr, flush=True)
        return 1
    if sess is None:
        print(f"host {name}: stopped before a router answered", flush=True)
        return 0
    with sess:
        host = Host(sess, name, robots, list(args.connect), settings, workdir, args.launcher_wait)
        queryable = sess.declare_queryable(host.keys.ctl)
        token = sess.liveliness().declare_token(host.keys.alive)
        host.say(
            f"connected to a router at {where}; serving robots {', '.join(map(str, robots)) if robots else 'any'} "
            f"(formation_swarm {__version__})"
        )
        try:
            while not stop.is_set():
                query = queryable.try_recv()
                if query is not None:
                    host.answer(query)
                    continue
                host.watch()
                stop.wait(0.02)
        finally:
            for run in list(host.runs.values()):
                host.end(run, "the host stopped")
            token.undeclare()
            queryable.undeclare()
    host.say("stopped")
    lock.close()  # the workdir is free for the next host (an exit of any kind frees it too)
    return 0


if __name__ == "__main__":
    sys.exit(main())
