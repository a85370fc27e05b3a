"""``swarm run``: one run, every robot its own process, on this machine.

Starts the world (which is also the Zenoh router, listening on a free
loopback port), the logger and one agent per robot; shows progress; stops
them all at the end, on Ctrl-C or when the world fails, and always reaps
them (a child also dies with the launcher: PR_SET_PDEATHSIG). The run folder
holds the scenario as run, recording.rrd, summary.json and logs/.

An agent or the logger that dies is reported in the summary and the run goes
on (the world stops a robot whose agent is gone); a world that dies ends the run,
and so does any process that dies before tick 0 (the world waits for them all).
A process that exits with an error is named on the console with its exit code
and the last lines of its log (logs/<name>.log), and in the summary's events.

The launcher executes the scenario's process faults on the world's calls
(``Keys.faults``, a FaultCall at the fault's tick, world.process_faults):
SIGKILL, a fresh agent for the same robot (its log ``logs/agent-N.2.log``,
its stats ``stats/agent-N.2.json``), SIGSTOP, SIGCONT. Each execution is an
event of the summary with the call's tick and sim time and the wall time.

With ``hosts`` (``swarm run --hosts a,b``) the agents run on other machines,
each started by that machine's ``swarm host`` (formation_swarm.nodes.host); the
world listens on ``listen``, an address the hosts reach, and is their router.
The launcher waits (with a deadline) for each host's token, checks its
version and the robots it may run, places the robots (``placement``, the
others round-robin), and starts them there; process faults on a remote agent
are executed by its host. At the end it fetches each remote agent's log and
stats into logs/ and stats/, and the summary says where each agent ran. A
host that goes mid-run has its robots counted dead, and the run fails naming it.
"""

from __future__ import annotations

import contextlib
import math
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
import uuid
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from formation_swarm.common.faults import Fault
from formation_swarm.common.version import __version__
from formation_swarm.launch import remote
from formation_swarm.launch.console import print_result as print_result  # re-exported: the API of swarm run
from formation_swarm.nodes import viewer
from formation_swarm.protocol import trust
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.hostmsg import HostReply, HostRequest
from formation_swarm.protocol.keys import Keys, check_host_name
from formation_swarm.protocol.messages import FaultCall, Status
from formation_swarm.protocol.session import listen_problem, loopback, make_config
from formation_swarm.runtime import proc
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.children import Child, describe_exit, free_port, log_tail
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.keys import ScenarioWarning

STOP_GRACE_S = 2.0
SECRETS = "secrets"  # the run's credentials (folder 0700, files 0600), deleted when the run ends
END_GRACE_S = 3.0
# How long an agent of a local run waits for the world's token to come back
# after it went. The world is the run's router here, and nothing restarts it:
# once gone it is gone. What does come back is a session the router dropped
# (an agent frozen beyond the Zenoh lease): its client reconnects and sees the
# world's token go and return together when it resumes (measured, Zenoh 1.10).
AGENT_WORLD_GRACE_S = 1.0
SIGNALS = {"kill": signal.SIGKILL, "freeze": signal.SIGSTOP, "thaw": signal.SIGCONT}


@dataclass
class RunResult:
    run_dir: Path
    summary: dict[str, Any] = field(repr=False)  # several kB: print res.summary to see it
    exit_code: int
    pids: dict[str, int] = field(default_factory=dict, repr=False)

    @property
    def recording(self) -> Path:
        return self.run_dir / "recording.rrd"


@dataclass
class KillAt:
    """``--kill agent-3@20``: the same as the fault ``kill agent-3@20s``."""

    who: str
    time_s: float

    @classmethod
    def parse(cls, text: str) -> KillAt:
        """``"agent-3@20"`` -> KillAt("agent-3", 20.0)."""
        who, sep, when = str(text).partition("@")
        try:
            time_s = float(when.removesuffix("s"))
        except ValueError:
            time_s = math.nan
        if not sep or not who or not math.isfinite(time_s) or time_s < 0:
            raise ValueError(f"a kill is PROCESS@SECONDS with SECONDS >= 0 (e.g. agent-3@20), got {text!r}")
        return cls(who, time_s)

    def fault(self) -> Fault:
        return Fault.make("kill", self.who, self.time_s)


def _as_fault(value: Fault | KillAt | str | Mapping[str, Any], kill: bool) -> Fault:
    if isinstance(value, KillAt):
        return value.fault()
    if kill and isinstance(value, str):
        return KillAt.parse(value).fault()
    return Fault.coerce(value)


class Launch:
    """One run. Use as a context manager: leaving it always stops and reaps."""

    def __init__(
        self,
        scenario_path: str | Path,
        *,
        mode: str = "lockstep",
        seed: int | None = None,
        out: str | Path | None = None,
        overrides: dict[str, Any] | None = None,
        logger: bool = True,
        live: str | None = None,
        serve_web: bool = False,
        web_ports: tuple[int, int] = (9876, 9090),
        kills: Sequence[KillAt | str] = (),
        faults: Sequence[Fault | str | Mapping[str, Any]] = (),
        progress: Callable[[str], None] | None = None,
        run_id: str | None = None,
        python: str = sys.executable,
        auth: bool = True,
        fork: bool = True,
        hosts: Sequence[str] = (),
        placement: Mapping[int, str] | None = None,
        listen: str | None = None,
        host_logins: str | Path | None = None,
        hosts_timeout_s: float = 30.0,
        tls: trust.Tls | None = None,
        rt_priority: int | None = None,
    ) -> None:
        if mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be 'lockstep' or 'realtime', got {mode!r}")
        if rt_priority is not None and not (mode == "realtime" and 0 <= rt_priority <= 99):
            raise ValueError(f"rt_priority: 0-99 and only in real time, got {rt_priority!r} in {mode}")
        self.rt_priority = rt_priority  # the real-time world's (None: swarm world's default)
        self.scenario_path = scenario_files.resolve(scenario_path)
        if overrides is not None and not isinstance(overrides, Mapping):
            raise ValueError(
                f"overrides must map scenario keys to values, e.g. {{'leader.speed_mps': 1.6}}, "
                f"got {type(overrides).__name__} {overrides!r:.80}"
            )
        ov = dict(overrides or {})
        if seed is not None:
            if "run.seed" in ov and ov["run.seed"] != seed:
                raise ValueError(f"seed {seed} and run.seed {ov['run.seed']!r} in the overrides: give the seed once")
            ov["run.seed"] = seed
        # One given alone (faults="kill agent-3@5s") is one, not a sequence of letters.
        kills = [kills] if isinstance(kills, str) else kills
        faults = [faults] if isinstance(faults, (str, Mapping, Fault)) else faults
        extra = [_as_fault(k, kill=True) for k in kills] + [_as_fault(f, kill=False) for f in faults]
        with warnings.catch_warnings():  # the loader's warnings are in sc.warnings: printed when the run starts
            warnings.simplefilter("ignore", ScenarioWarning)
            self.sc = scenario_mod.load(self.scenario_path, ov, extra)
        self.mode = mode
        self.run_id = run_id or f"{_slug(self.sc.name)}-{uuid.uuid4().hex[:8]}"
        Keys(self.run_id)  # validates
        self.run_dir = Path(out) if out is not None else Path("runs") / self.run_id
        self.logger = logger
        self.live = live
        self.serve_web = serve_web
        self.web_ports = web_ports  # (gRPC, web viewer), with serve_web
        if serve_web:  # checked now: a logger that cannot serve would fail the run after it started
            for flag, p in zip(("--grpc-port", "--web-port"), web_ports, strict=True):
                if (why := viewer.port_taken(p)) is not None:
                    raise ValueError(f"{flag} {p}: cannot serve the web viewer there ({why}); choose another port")
        self.said_web = False  # the web viewer's address is on the console
        self.progress = progress or (lambda line: print(line, flush=True))
        for warning in self.sc.warnings:  # the loader's, with the run's other console lines
            self.progress(f"[swarm] warning: {warning}")
        self.python = python
        self.fork = fork  # our roles forked from the spawner, else exec'd (formation_swarm.runtime.spawner)
        self.tls = tls  # with hosts: the router's TLS identity on --listen (its local endpoint stays on loopback)
        self.auth = auth  # every process logs in with its own fresh credentials; the world enforces the rules
        self.port = 0
        self.children: dict[str, Child] = {}
        self.session: zenoh.Session | None = None
        self.token: zenoh.LivelinessToken | None = None  # held: a dropped token is undeclared
        self.status_q: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        self.last_status: Status | None = None
        self.first_status: Status | None = None  # the world's first status: the run's start
        self.calls_q: queue.SimpleQueue[bytes] = queue.SimpleQueue()  # the world's fault calls
        self.call_rejections = Rejections()
        self.last_call_seq = 0
        self.current: dict[str, str] = {}  # a process of the scenario -> its newest child (agent-3 -> agent-3.2)
        self.frozen: set[str] = set()  # children stopped by SIGSTOP
        self.frozen_by: dict[str, str] = {}  # the fault that froze (or thawed) each, last
        self.events: list[dict[str, Any]] = []
        self.started_at = 0.0
        self._interrupt = threading.Event()  # interrupt(): another thread's Ctrl-C (a sweep's runs)
        self.said_windows: set[tuple[str, int]] = set()  # the link/sensor/actuator faults' starts and ends said
        for f in self.sc.faults:
            if f.process is not None and f.process not in self._names():
                why = " (the run has no logger: --no-logger, or logger=False)" if f.process == "logger" else ""
                raise ValueError(f"cannot {f.kind} {f.process!r}{why}: processes are {', '.join(self._names()[1:])}")
        self.process_faults = any(f.process is not None for f in self.sc.faults)
        self._setup_hosts(hosts, placement, listen, host_logins, hosts_timeout_s)

    def _setup_hosts(
        self,
        hosts: Sequence[str],
        placement: Mapping[int, str] | None,
        listen: str | None,
        host_logins: str | Path | None,
        timeout_s: float,
    ) -> None:
        self.hosts = [check_host_name(h) for h in hosts]
        if len(set(self.hosts)) != len(self.hosts):
            raise ValueError(f"--hosts names a host twice: {','.join(self.hosts)}")
        # The scenario's [placement], then --place; a run on this machine alone ignores both.
        self.explicit = {**dict(self.sc.placement), **dict(placement or {})} if self.hosts else {}
        if placement and not self.hosts:
            raise ValueError("a placement needs --hosts")
        for rid, h in self.explicit.items():
            if rid not in self.sc.robots:
                robots = ", ".join(map(str, self.sc.robots))
                raise ValueError(f"placement {rid}={h}: no robot {rid}; robots are {robots}")
            if h not in self.hosts:
                raise ValueError(f"placement {rid}={h}: {h} is not one of --hosts {','.join(self.hosts)}")
        self.listen = listen
        if self.hosts and not listen:
            raise ValueError(
                "--hosts needs --listen ENDPOINT: where the world listens for the hosts' agents, "
                "e.g. tcp/192.168.1.10:7447 (an address every host reaches)"
            )
        if self.hosts and listen:  # checked before anything starts: a run that cannot listen fails a bad command
            try:
                why = listen_problem(listen)
            except ValueError as exc:
                raise ValueError(f"--listen {listen}: {exc}") from None
            if why is not None:
                raise ValueError(
                    f"--listen {listen}: cannot listen there ({why}); give a free port of an address of this machine"
                )
        self.host_logins = None
        if self.tls is not None and not (self.hosts and self.auth and listen and listen.startswith("tls/")):
            raise ValueError("TLS files are for --hosts with --listen tls/ADDRESS:PORT and logins")
        if self.hosts and listen and listen.startswith("tls/") and self.tls is None:
            raise ValueError(
                f"--listen {listen}: a TLS router needs --tls-ca, --tls-cert and --tls-key (the CA the "
                "hosts trust, this router's certificate and key)"
            )
        if self.hosts and listen and listen.startswith("tcp/") and not loopback(listen):
            self.progress(
                f"[swarm] warning: --listen {listen} is plain TCP: the hosts get their agents' passwords, "
                "and the run's data crosses the network, unencrypted (deploy/README.md: TLS)"
            )
        if self.hosts and self.auth:
            if host_logins is None:
                raise ValueError(
                    "--hosts needs --host-logins FILE: the hosts' logins the run's router lets in "
                    "(swarm secure --hosts NAMES writes it)"
                )
            self.host_logins = trust.read_host_logins(host_logins, self.hosts)
        self.hosts_timeout_s = timeout_s
        self.clients: dict[str, remote.HostClient] = {}
        self.poller: remote.Poller | None = None
        self.placement: dict[int, str] = {}
        self.host_infos: dict[str, HostReply] = {}
        self.lost_hosts: list[str] = []

    def _names(self) -> list[str]:
        return ["world", *(["logger"] if self.logger else []), *(f"agent-{r}" for r in self.sc.robots)]

    @property
    def endpoint(self) -> str:
        """Where this machine's processes reach the router (the world, or with
        hosts the launcher, which listens on ``listen`` for the hosts too)."""
        return f"tcp/127.0.0.1:{self.port}"

    # -- lifecycle ----------------------------------------------------------------
    def __enter__(self) -> Launch:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self) -> None:
        """Spawn every process (once); on any failure (Ctrl-C included) reap what started."""
        if self.children:
            return
        try:
            self._start()
        except BaseException as exc:
            self._watch()  # a child that already failed (the world, say) explains itself
            self.stop(graceful_first=False)
            host_failed = isinstance(exc, (remote.HostError, ValueError))  # a host missing, refusing, unfit
            if host_failed:
                self.events.append({"event": "start failed", "why": str(exc)})
            if self.run_dir.exists():
                self._summary(1 if host_failed else 130, interrupted=not host_failed, timed_out=False)
            raise

    def _start(self) -> None:
        self.run_dir.mkdir(parents=True, exist_ok=True)
        (self.run_dir / "logs").mkdir(exist_ok=True)
        (self.run_dir / "stats").mkdir(exist_ok=True)
        scenario_file = self.run_dir / "scenario.toml"
        scenario_file.write_text(scenario_files.dumps(self.sc.raw))
        self.port = free_port()
        common = ["--scenario", str(scenario_file), "--run", self.run_id]
        secrets = (
            trust.write_run_secrets(
                self.run_dir / SECRETS,
                self.run_id,
                self.sc.robots,
                self.sc.leader.robot_id,
                world_is_router=not self.hosts,
                host_logins=self.host_logins,
                tls=self.tls,
            )
            if self.auth
            else {}
        )

        def auth(user: str) -> list[str]:
            return ["--auth", str(secrets[user])] if secrets else []

        def py(module: str) -> list[str]:
            return [self.python, "-m", f"formation_swarm.{module}"]

        stats = self.run_dir / "stats"
        # With hosts, the launcher is the router (it outlives the world: the hosts are
        # reached through it until their agents' logs are fetched); else the world is.
        zenoh_role = (
            ["--zenoh-mode", "client", "--connect", self.endpoint, *auth("world")]
            if self.hosts
            else ["--zenoh-mode", "router", "--listen", self.endpoint, *auth("router")]
        )
        if self.hosts:
            assert self.listen is not None
            settings = trust.read_settings(secrets["router"]) if secrets else None
            conf = make_config("router", listen=[self.listen, self.endpoint], settings=settings)
            self.session = zenoh.open(conf)
            trust.forget_router_secrets(self.run_dir / SECRETS)  # read: the hosts' lasting logins leave the disk
        specs = {
            "world": [
                *py("nodes.world"),
                *common,
                "--mode",
                self.mode,
                "--stats",
                str(stats / "world.json"),
                *zenoh_role,
                *["--expect-logger"] * self.logger,
                *["--process-faults"] * self.process_faults,
                *(["--rt-priority", str(self.rt_priority)] if self.rt_priority is not None else []),
            ],
        }
        if self.logger:
            extra = ["--live", self.live] if self.live else []
            if self.live and (why := viewer.unreachable(self.live)) is not None:
                # Said here, once: the logger's own line would end in its log.
                self.progress(
                    f"[swarm] --live {self.live}: no Rerun viewer answers there ({why}); not streaming "
                    "there, the run is recorded to recording.rrd only"
                )
                extra = []
            if self.serve_web:
                extra += ["--serve-web", "--grpc-port", str(self.web_ports[0]), "--web-port", str(self.web_ports[1])]
            specs["logger"] = [
                *py("nodes.logger"),
                *common,
                "--out",
                str(self.run_dir / "recording.rrd"),
                "--stats",
                str(stats / "logger.json"),
                "--connect",
                self.endpoint,
                *extra,
                *auth("logger"),
            ]
        for rid in [] if self.hosts else self.sc.robots:
            agent_stats = str(stats / f"agent-{rid}.json")
            specs[f"agent-{rid}"] = [
                *py("nodes.agent"),
                "--id",
                str(rid),
                *common,
                "--stats",
                agent_stats,
                "--connect",
                self.endpoint,
                "--world-grace",
                f"{AGENT_WORLD_GRACE_S:g}",
                *(["--lockstep"] if self.mode == "lockstep" else []),
                *auth(trust.agent_user(rid)),
            ]
        self.started_at = time.monotonic()
        for name, argv in specs.items():
            child = Child(name, argv, self.run_dir / "logs" / f"{name}.log", fork=self.fork)
            self.children[name] = child
            self.current[name] = name
            child.start()
        if self.session is None:
            settings = trust.read_settings(secrets["launcher"]) if secrets else None
            conf = make_config("client", [self.endpoint], connect_timeout_s=30.0, settings=settings)
            self.session = zenoh.open(conf)
        keys = Keys(self.run_id)
        self.session.declare_subscriber(keys.status, lambda s: self.status_q.put(s.payload.to_bytes()))
        self.session.declare_subscriber(keys.faults, lambda s: self.calls_q.put(s.payload.to_bytes()))
        # After the subscriber: with process faults the world waits for this token before tick 0.
        self.token = self.session.liveliness().declare_token(keys.alive("launcher", 0))
        if self.hosts:
            self._start_remote(secrets)

    def _start_remote(self, secrets: Mapping[str, Path]) -> None:
        """Wait for the hosts, check them, place the robots, start their agents."""
        assert self.session is not None
        self.clients = {h: remote.HostClient(self.session, h) for h in self.hosts}
        deadline = time.monotonic() + self.hosts_timeout_s
        if not all(c.present.wait(0.2) for c in self.clients.values()):  # said only if it takes a while
            missing = [h for h, c in self.clients.items() if not c.present.is_set()]
            self.progress(
                f"[swarm] waiting up to {self.hosts_timeout_s:g} s for host{'s' if len(missing) > 1 else ''} "
                f"{', '.join(missing)} to connect to {self.listen}"
            )
        for h, client in self.clients.items():
            if not client.present.wait(max(0.0, deadline - time.monotonic())):
                raise remote.HostError(
                    f"host {h} did not connect to {self.listen} within {self.hosts_timeout_s:g} s: start "
                    f"'swarm host --connect <this address> --name {h} --auth host-{h}.json' there, and check "
                    "its --connect, its login and the network"
                )
            client.info = self.host_infos[h] = client.ask(HostRequest("info", __version__))
        allowed = {h: info.robots for h, info in self.host_infos.items()}
        self.placement = remote.place(self.sc.robots, self.hosts, allowed, self.explicit)
        if idle := [h for h in self.hosts if h not in self.placement.values()]:
            self.progress(
                f"[swarm] warning: host{'s' if len(idle) > 1 else ''} {', '.join(idle)} "
                f"run{'' if len(idle) > 1 else 's'} no robot (the placement gave them none)"
            )
        scenario_text = (self.run_dir / "scenario.toml").read_text()
        for rid, h in self.placement.items():
            self.progress(f"[swarm] agent-{rid} on host {h}")
            self._start_agent_on(f"agent-{rid}", h, scenario_text, secrets)
        self.poller = remote.Poller(list(self.clients.values()), self.run_id)

    def _start_agent_on(self, name: str, host: str, scenario_text: str, secrets: Mapping[str, Path]) -> str:
        rid = int(name.split(".")[0].removeprefix("agent-"))
        user, password = trust.agent_user(rid), ""
        if secrets:
            password = trust.read_settings(secrets[user])["transport/auth/usrpwd"]["password"]
        req = HostRequest(
            "start",
            __version__,
            run=self.run_id,
            process=name,
            scenario=scenario_text,
            user=user,
            password=password,
            world_grace_s=AGENT_WORLD_GRACE_S,
            lockstep=self.mode == "lockstep",
        )
        child = remote.RemoteChild(
            name, [], self.run_dir / "logs" / f"{name}.log", client=self.clients[host], run=self.run_id, request=req
        )
        self.children[name] = child
        self.current[name.split(".")[0]] = name
        child.start()
        return name

    def pids(self) -> dict[str, int]:
        return {n: c.pid for n, c in self.children.items() if c.pid is not None}

    def sim_time(self) -> float:
        self._read_status()
        return -1.0 if self.last_status is None else self.last_status.time_s

    def _read_status(self) -> None:
        rej = Rejections()
        while True:
            try:
                payload = self.status_q.get_nowait()
            except queue.Empty:
                return
            st = rej.decode(Status, payload)
            if st is not None and (self.first_status is None or st.seq < self.first_status.seq):
                self.first_status = st
            if st is not None and (self.last_status is None or st.seq > self.last_status.seq):
                self.last_status = st

    def interrupt(self) -> None:
        """Stop the run as a Ctrl-C would, from any thread: :meth:`wait` stops
        every process and ends with exit code 130, the summary ``interrupted``."""
        self._interrupt.set()

    def wait_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Poll ``predicate`` (and watch the children) until true or the timeout."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return True
            self._watch()
            if self.children["world"].poll() is not None:
                return predicate()
            time.sleep(0.02)
        return False

    def _watch(self) -> None:
        self._read_status()
        # The world's calls before the thaw at its end: a lockstep run may pass a
        # freeze's tick and end between two looks (20 ticks take 20 ms here), and
        # a freeze carried out after the thaw would hold its process to the end.
        self._execute_calls()
        self._say_windows()
        self._thaw_at_end()
        t = self.sim_time()
        if self.serve_web and self.logger and not self.said_web and self.last_status is not None:
            # The world starts once the logger is there, serving: the address works now.
            self.said_web = True
            self.progress(f"[swarm] watch the run in a browser: {viewer.web_address(*self.web_ports)}")
        for h, client in self.clients.items():
            if client.lost and not client.reported:
                client.reported = True
                self.lost_hosts.append(h)
                robots = [r for r, ph in self.placement.items() if ph == h]
                self.events.append(
                    {
                        "event": "host lost",
                        "host": h,
                        "robots": robots,
                        "sim_time_s": t,
                        "wall_s": time.monotonic() - self.started_at,
                    }
                )
                wall = time.monotonic() - self.started_at
                dead = f"robot{'s' if len(robots) > 1 else ''} {', '.join(map(str, robots))}" if robots else "none"
                self.progress(
                    f"[swarm] host {h} was lost {wall:.1f} s of wall time into the run (its token went): "
                    f"{dead} counted dead"
                )
        for child in self.children.values():
            code = child.poll()
            if code is not None and not child.reported:
                child.reported = True
                if code != 0 and child.stop_sent_at is None:
                    self._exited(child, code, t)

    def _execute_calls(self) -> None:
        """The world's fault calls that have come, in order: a signal, or a fresh agent."""
        while True:
            try:
                payload = self.calls_q.get_nowait()
            except queue.Empty:
                return
            call = self.call_rejections.decode(FaultCall, payload)
            if call is None:
                continue
            faults = self.sc.faults
            if call.index >= len(faults) or faults[call.index].process != call.process:
                self.call_rejections.reject("not a fault of the schedule")
                continue
            if call.seq <= self.last_call_seq:
                self.call_rejections.reject("replayed or reordered")
                continue
            self.last_call_seq = call.seq
            self._execute(call, faults[call.index])

    def _say_windows(self) -> None:
        """The schedule's faults the world applies itself (link, sensor, actuator):
        a line when the run passes each one's start and end, as the process
        faults get when they are carried out (as soon as a status says the
        tick is passed: up to a status period late)."""
        st = self.last_status
        if st is None:
            return
        dt = self.sc.dt_s
        for i, f in enumerate(self.sc.faults):
            if f.process is not None:
                continue
            start, end = f.start_tick(dt), f.end_tick(dt)
            if st.tick >= start and ("on", i) not in self.said_windows:
                self.said_windows.add(("on", i))
                self.progress(f"[swarm] fault on from tick {start}, sim t={start * dt:.2f} s ('{f}')")
            if end is not None and st.tick >= end and ("off", i) not in self.said_windows:
                self.said_windows.add(("off", i))
                self.progress(f"[swarm] fault off from tick {end}, sim t={end * dt:.2f} s ('{f}')")

    def _thaw_at_end(self) -> None:
        """Once the world has said "done", a process still frozen by a fault that
        outlasts the run is thawed: it could not leave, and the world and the
        followers would wait for it (the logger: up to 10 s)."""
        if not self.frozen or self.last_status is None or self.last_status.state != "done":
            return
        for name in sorted(self.frozen):
            self.children[name].signal(signal.SIGCONT)
            st = self.last_status
            self.events.append(
                {
                    "event": "thawed",
                    "process": name,
                    "fault": self.frozen_by.get(name),
                    "why": "the run's end",
                    "sim_time_s": st.time_s,
                    "tick": st.tick,
                    "wall_s": time.monotonic() - self.started_at,
                }
            )
            self.progress(f"[swarm] thawed {name} at the run's end (its freeze outlasted the run)")
        self.frozen.clear()

    def _execute(self, call: FaultCall, fault: Fault) -> None:
        name = self.current[call.process]
        child = self.children[name]
        if call.action == "start":
            name = self._restart(call.process)
        else:
            child.signal(SIGNALS[call.action])
            (self.frozen.add if call.action == "freeze" else self.frozen.discard)(name)
            self.frozen_by[name] = str(fault)
        done = {"kill": "killed", "start": "started", "freeze": "frozen", "thaw": "thawed"}[call.action]
        self.events.append(
            {
                "event": done,
                "process": name,
                "fault": str(fault),
                "tick": call.tick,
                "sim_time_s": call.time_s,
                "wall_s": time.monotonic() - self.started_at,
                "pid": self.children[name].pid,
            }
        )
        self.progress(f"[swarm] {done} {name} at tick {call.tick}, sim t={call.time_s:.2f} s ('{fault}')")

    def _restart(self, process: str) -> str:
        """A fresh process for ``process`` (an agent), as the first was started
        but with its own log and stats file; its name (agent-3.2, ...)."""
        old = self.children[self.current[process]]
        if isinstance(old, remote.RemoteChild):
            old.signal(signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                old.proc.wait(timeout=5.0)  # type: ignore[union-attr]
            n = 2
            while f"{process}.{n}" in self.children:
                n += 1
            return self._start_agent_on(
                f"{process}.{n}", old.host, (self.run_dir / "scenario.toml").read_text(), self._secrets()
            )
        if old.proc is not None:  # SIGKILLed at the kill call: reaped first, so its token is gone
            old.signal(signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                old.proc.wait(timeout=5.0)
        n = 2
        while f"{process}.{n}" in self.children:
            n += 1
        name = f"{process}.{n}"
        argv = list(self.children[process].argv)
        argv[argv.index("--stats") + 1] = str(self.run_dir / "stats" / f"{name}.json")
        child = Child(name, argv, self.run_dir / "logs" / f"{name}.log", fork=self.fork)
        self.children[name] = child
        self.current[process] = name
        child.start()
        return name

    def _exited(self, child: Child, code: int, t: float) -> None:
        """A child that ended on its own, with an error: an event, and on the
        console which one, how, and the last lines of its log."""
        if isinstance(child, remote.RemoteChild) and child.host in self.lost_hosts:
            # Its exit code stayed on that host (remote.LOST_CODE stands for it here): none is made up.
            self.events.append({"event": "exited", "process": child.name, "sim_time_s": t, "host_lost": child.host})
            return
        kill = next((e for e in self.events if e["event"] == "killed" and e["process"] == child.name), None)
        if kill is not None:
            # By fault injection, already said; it died at the kill (the status may lag behind).
            at = kill.get("sim_time_s", t)
            self.events.append(
                {"event": "exited", "process": child.name, "code": code, "sim_time_s": at, "tick": kill.get("tick")}
            )
            return
        tail = log_tail(child.log_path)
        self.events.append({"event": "exited", "process": child.name, "code": code, "sim_time_s": t, "log_tail": tail})
        when = "before the run started" if self.last_status is None else f"at sim t={t:.2f} s"
        self.progress(f"[swarm] {child.name} {describe_exit(code)} {when}; the end of {child.log_path}:")
        for line in tail or ["(the log is empty)"]:
            self.progress(f"  | {line}")

    def _failed_to_start(self) -> list[str]:
        """The children that ended with an error before tick 0: the world waits
        for every agent and the logger, so the run cannot start without them."""
        if self.last_status is not None:
            return []
        return [c.name for c in self.children.values() if c.poll() not in (None, 0) and c.stop_sent_at is None]

    def wait(self, timeout_s: float | None = None) -> RunResult:
        """Run to the end (or timeout/Ctrl-C), stop everything, write the summary."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        interrupted = timed_out = start_failed = False
        last_line = 0.0
        shown: int | None = None  # the tick of the last progress line
        world = self.children["world"]
        try:
            while world.poll() is None:
                self._watch()
                now = time.monotonic()
                if failed := self._failed_to_start():
                    start_failed = True
                    self.progress(f"[swarm] the run cannot start without {', '.join(failed)}: stopping every process")
                    break
                if shown is None and self.first_status is not None:
                    # The run's start first, even when its end is already queued behind it
                    # (a short lockstep run may be over before this loop's first look).
                    shown = self._show_progress(self.first_status)
                    last_line = now
                elif now - last_line >= 2.0 and self.last_status is not None:
                    shown = self._show_progress()
                    last_line = now
                if deadline is not None and now > deadline:
                    timed_out = True
                    self.progress(f"[swarm] timeout after {timeout_s:g} s: stopping the run")
                    break
                if self._interrupt.wait(0.05):
                    raise KeyboardInterrupt
        except KeyboardInterrupt:
            interrupted = True
            self.progress("[swarm] interrupted: stopping every process")
        self._watch()
        if self.last_status is not None and self.last_status.tick != shown and not interrupted:
            self._show_progress()  # where it ended: a run shorter than a line's 2 s showed only its start
        self.stop(graceful_first=not (interrupted or timed_out or start_failed))
        for child in self.children.values():  # codes the fork server did not report, taken from the child's record
            if getattr(child.proc, "unreported", False):
                self.events.append(
                    {
                        "event": "exit code not reported by the fork server",
                        "process": child.name,
                        "code": child.proc.returncode,
                    }
                )
        world_code = world.proc.returncode if world.proc is not None else None
        code = 130 if interrupted else (124 if timed_out else (0 if world_code == 0 and not start_failed else 1))
        if code == 0 and (lost := summary_mod.run_failed(summary_mod.read_parts(self.run_dir / "stats"), self.sc)):
            self.progress(f"[swarm] the run failed: {lost}")
            code = 1  # it ran to its end, but not as a formation: not a success
        if code in (0, 1) and self.lost_hosts:
            for h in self.lost_hosts:
                robots = ", ".join(str(r) for r, ph in self.placement.items() if ph == h)
                self.progress(f"[swarm] the run failed: host {h} was lost; its robots ({robots}) were counted dead")
            code = 1
        summary = self._summary(code, interrupted, timed_out, timeout_s if timed_out else None)
        return RunResult(self.run_dir, summary, code, self.pids())

    def _show_progress(self, st: Status | None = None) -> int:
        """Print a status's tick (the last one's by default), share of the run and sim time; its tick."""
        st = st or self.last_status
        assert st is not None
        pct = 100.0 * st.tick / max(1, st.total_ticks)
        self.progress(f"[swarm] tick {st.tick}/{st.total_ticks} ({pct:.0f}%), sim {st.time_s:.1f} s")
        return st.tick

    def stop(self, graceful_first: bool = True) -> None:
        """End of run: give everyone END_GRACE_S to leave on the world's "done",
        then SIGTERM, then SIGKILL after STOP_GRACE_S. Always reaps; a second
        Ctrl-C meanwhile does not interrupt the reaping."""
        with proc.sigint_ignored():
            self._stop(graceful_first)

    def _stop(self, graceful_first: bool) -> None:
        for name in self.frozen:  # a stopped process hears no SIGTERM, nor the end of the run
            self.children[name].signal(signal.SIGCONT)
        self.frozen.clear()
        if graceful_first:
            self._wait_exit(END_GRACE_S)
        for c in self.children.values():
            c.signal(signal.SIGTERM)
        self._wait_exit(STOP_GRACE_S + 1.0)
        for c in self.children.values():
            if c.poll() is None:
                self.events.append({"event": "killed after stop timeout", "process": c.name})
                c.signal(signal.SIGKILL)
        for c in self.children.values():
            if c.proc is not None:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    c.proc.wait(timeout=5.0)
                c.poll()
            c.close()
        self._stop_remote()
        if self.session is not None:
            self.session.close()
            self.session = None
        # Every process that held a password is gone: they are of no use now.
        shutil.rmtree(self.run_dir / SECRETS, ignore_errors=True)

    def _secrets(self) -> dict[str, Path]:
        folder = self.run_dir / SECRETS
        return {p.stem: p for p in folder.glob("*.json")} if self.auth else {}

    def _stop_remote(self) -> None:
        """Fetch the remote agents' logs and stats, end the run on every host."""
        if not self.clients:
            return
        if self.poller is not None:
            self.poller.close()
            self.poller = None
        for c in self.children.values():
            if isinstance(c, remote.RemoteChild) and (why := c.fetch(self.run_dir / "stats")) is not None:
                self.events.append({"event": "not fetched", "process": c.name, "host": c.host, "why": why})
        for client in self.clients.values():
            if not client.lost:
                with contextlib.suppress(remote.HostError):
                    client.ask(HostRequest("end", __version__, run=self.run_id))
            client.close()
        self.clients = {}

    def _wait_exit(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline and any(c.poll() is None for c in self.children.values()):
            time.sleep(0.02)

    # -- summary ------------------------------------------------------------------
    def _summary(self, code: int, interrupted: bool, timed_out: bool, limit_s: float | None = None) -> dict[str, Any]:
        parts = summary_mod.read_parts(self.run_dir / "stats")
        if self.call_rejections.total:  # fault calls refused: counted like every receiver's rejections
            parts["launcher"] = {"rejected": dict(self.call_rejections.by_reason)}
        world = parts.get("world", {})
        world_proc = self.children["world"].proc if "world" in self.children else None
        reached = world.get("sim_time_s")
        if reached is None and self.last_status is not None:
            reached = self.last_status.time_s
        if interrupted:
            reason = summary_mod.INTERRUPTED
        elif any(e.get("event") == "start failed" for e in self.events):
            reason = summary_mod.START_FAILED
        elif timed_out:
            reason = summary_mod.TIMED_OUT
        elif world_proc is not None and world_proc.returncode == 0 and world.get("end_reason"):
            reason, reached = world["end_reason"], world.get("ended_at_s")
        else:
            reason = summary_mod.ROLE_FAILED
        procs = {}
        for name, c in self.children.items():
            exit_after_stop = None
            if c.stop_sent_at is not None and c.exited_at is not None:
                exit_after_stop = max(0.0, c.exited_at - c.stop_sent_at)
            procs[name] = {
                "pid": c.pid,
                "exit_code": None if c.proc is None else c.proc.returncode,
                "exit_after_stop_s": exit_after_stop,
            }
            if isinstance(c, remote.RemoteChild) and c.host in self.lost_hosts:
                procs[name].update(exit_code=None, lost_with_host=c.host)
        summary = summary_mod.build(
            run_id=self.run_id,
            sc=self.sc,
            mode=self.mode,
            parts=parts,
            exit_code=code,
            end_reason=reason,
            ended_at_s=reached,
            interrupted=interrupted,
            timed_out=timed_out,
            limit_s=limit_s,
            processes=procs,
            events=self.events,
            recording="recording.rrd" if self.logger else None,
        )
        if self.hosts:
            summary["placement"] = {f"agent-{r}": h for r, h in self.placement.items()}
            summary["hosts"] = {
                h: {
                    "hostname": i.hostname,
                    "cores": i.cores,
                    "free_mem_mb": i.free_mem_mb,
                    "version": i.version,
                    "lost": h in self.lost_hosts,
                }
                for h, i in self.host_infos.items()
            }
            for name, proc in summary.get("processes", {}).items():
                child = self.children.get(name)
                proc["host"] = child.host if isinstance(child, remote.RemoteChild) else "local"
        summary_mod.write(self.run_dir, summary)
        return summary


def _slug(name: str) -> str:
    out = "".join(ch if ch.isalnum() or ch in "-_" else "-" for ch in name).strip("-")
    return out[:40] or "run"
