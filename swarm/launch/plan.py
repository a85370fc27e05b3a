"""A run before it starts: its options checked, its scenario loaded, and what
each process is told: its command line, or a remote agent's start request,
and its login."""

from __future__ import annotations

import math
import sys
import uuid
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from formation_swarm.common.faults import Fault
from formation_swarm.common.version import __version__
from formation_swarm.launch import external as external_mod
from formation_swarm.launch import ros2 as ros2_mod
from formation_swarm.launch import sharing
from formation_swarm.nodes.logger import viewer
from formation_swarm.protocol import acl, trust
from formation_swarm.protocol.hostmsg import HostRequest
from formation_swarm.protocol.keys import Keys
from formation_swarm.runtime.spool import path_for as spool_path
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.keys import ScenarioWarning

# The run's credentials (folder 0700, files 0600): each process deletes its own
# once read (--auth-once), the folder goes when the run ends.
SECRETS = "secrets"
# How long an agent of a local run waits for the world's token to come back
# after it went. The world is the run's router here, and nothing restarts it:
# once gone it is gone. What does come back is a session the router dropped
# (an agent frozen beyond the Zenoh lease): its client reconnects and sees the
# world's token go and return together when it resumes (measured, Zenoh 1.10).
AGENT_WORLD_GRACE_S = 1.0


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


@dataclass(frozen=True, kw_only=True)
class RunOptions:
    """The keywords of :class:`~formation_swarm.launch.launcher.Launch` about
    the run on this machine, with their defaults."""

    mode: str = "lockstep"  # or "realtime"
    seed: int | None = None  # the scenario's run.seed when None
    out: str | Path | None = None  # the run folder (runs/<run id> when None)
    overrides: Mapping[str, Any] | None = None  # scenario keys, e.g. {"leader.speed_mps": 1.6}
    logger: bool = True
    # Every receiver spools what it takes, merged into wire.mcap (docs/replay.md): under 5% of the lockstep rate.
    record_wire: bool = True
    live: str | None = None  # a Rerun viewer's URL the logger also streams to
    serve_web: bool = False
    web_ports: tuple[int, int] = (9876, 9090)  # (gRPC, web viewer), with serve_web
    kills: Sequence[KillAt | str] | str = ()
    faults: Sequence[Fault | str | Mapping[str, Any]] | Fault | str | Mapping[str, Any] = ()
    progress: Callable[[str], None] | None = None  # the console (print when None)
    run_id: str | None = None
    python: str = sys.executable
    auth: bool = True  # every process logs in with its own fresh credentials; the world enforces the rules
    fork: bool = True  # our roles forked from the spawner, else exec'd (formation_swarm.runtime.spawner)
    rt_priority: int | None = None  # the real-time world's (None: swarm world's default)
    external: Sequence[int] | int = ()  # robots whose agent someone else starts (launch.external)
    observer_login: str | Path | None = None  # write a read-only login for the run here (launch.external)
    peers_timeout_s: float | None = None  # every role's wait for the others at the start (None: their default)


def _as_fault(value: Fault | KillAt | str | Mapping[str, Any], kill: bool) -> Fault:
    if isinstance(value, KillAt):
        return value.fault()
    if kill and isinstance(value, str):
        return KillAt.parse(value).fault()
    return Fault.coerce(value)


def _slug(name: str) -> str:
    out = "".join(ch if ch.isalnum() or ch in "-_" else "-" for ch in name).strip("-")
    return out[:40] or "run"


def _check_options(opts: RunOptions) -> None:
    if opts.mode not in ("lockstep", "realtime"):
        raise ValueError(f"mode must be 'lockstep' or 'realtime', got {opts.mode!r}")
    rt = opts.rt_priority
    if rt is not None and not (opts.mode == "realtime" and 0 <= rt <= 99):
        raise ValueError(f"rt_priority: 0-99 and only in real time, got {rt!r} in {opts.mode}")
    if opts.observer_login is not None and (not opts.auth or Path(opts.observer_login).is_dir()):
        why = "a folder; give a file name" if opts.auth else "a run without logins (auth=False) has none to give"
        raise ValueError(f"observer_login {opts.observer_login}: {why}")
    wait = opts.peers_timeout_s
    if wait is not None and (isinstance(wait, bool) or not isinstance(wait, (int, float)) or not 0 < wait <= 1e6):
        raise ValueError(f"peers_timeout_s: a number of seconds in (0, 1e6], got {wait!r}")


def _load(path: Path, opts: RunOptions) -> scenario_mod.Scenario:
    """The scenario with the options' overrides, seed, kills and faults."""
    if opts.overrides is not None and not isinstance(opts.overrides, Mapping):
        raise ValueError(
            f"overrides must map scenario keys to values, e.g. {{'leader.speed_mps': 1.6}}, "
            f"got {type(opts.overrides).__name__} {opts.overrides!r:.80}"
        )
    ov = dict(opts.overrides or {})
    if opts.seed is not None:
        if "run.seed" in ov and ov["run.seed"] != opts.seed:
            raise ValueError(f"seed {opts.seed} and run.seed {ov['run.seed']!r} in the overrides: give the seed once")
        ov["run.seed"] = opts.seed
    # One given alone (faults="kill agent-3@5s") is one, not a sequence of letters.
    kills = [opts.kills] if isinstance(opts.kills, str) else opts.kills
    faults = [opts.faults] if isinstance(opts.faults, (str, Mapping, Fault)) else opts.faults
    extra = [_as_fault(k, kill=True) for k in kills] + [_as_fault(f, kill=False) for f in faults]
    with warnings.catch_warnings():  # the loader's warnings are in sc.warnings: printed when the run starts
        warnings.simplefilter("ignore", ScenarioWarning)
        return scenario_mod.load(path, ov, extra)


@dataclass(frozen=True)
class Plan:
    """The run's options checked and its scenario loaded: every process's command line."""

    options: RunOptions
    scenario_path: Path
    sc: scenario_mod.Scenario
    run_id: str
    run_dir: Path
    external: tuple[int, ...] = ()  # robots whose agent the launcher does not start
    bridge: bool = False  # a ROS 2 bridge, as [ros2] bridge says; the external robots are then ROS's (launch.ros2)
    ros2_robots: tuple[int, ...] = ()  # robots driven from ROS 2 through the bridge

    @classmethod
    def make(cls, scenario_path: str | Path, options: RunOptions) -> Plan:
        """ValueError (or ScenarioError) for a bad option, before anything starts."""
        _check_options(options)
        path = scenario_files.resolve(scenario_path)
        sc = _load(path, options)
        run_id = options.run_id or f"{_slug(sc.name)}-{uuid.uuid4().hex[:8]}"
        Keys(run_id)  # validates
        run_dir = Path(options.out) if options.out is not None else Path("runs") / run_id
        if options.serve_web:  # checked now: a logger that cannot serve would fail the run after it started
            for flag, p in zip(("--grpc-port", "--web-port"), options.web_ports, strict=True):
                if (why := viewer.port_taken(p)) is not None:
                    raise ValueError(f"{flag} {p}: cannot serve the web viewer there ({why}); choose another port")
        external = external_mod.check(sc, options.external)
        bridge, ros2 = ros2_mod.check(sc, external)
        return cls(options, path, sc, run_id, run_dir, () if bridge else external, bridge, ros2)

    @property
    def own_robots(self) -> list[int]:
        """The robots whose agent the launcher starts (all but the external ones)."""
        return [r for r in self.sc.robots if r not in self.external and r not in self.ros2_robots]

    def names(self) -> list[str]:
        """The run's own processes: the world, the logger, one agent per robot not external."""
        return ["world", *(["logger"] if self.options.logger else []), *(f"agent-{r}" for r in self.own_robots)]

    def check_process_faults(self) -> None:
        """ValueError for a process fault whose process the run does not have."""
        names = self.names()
        for f in self.sc.faults:
            if f.process is not None and f.process not in names:
                why = " (the run has no logger: --no-logger, or logger=False)" if f.process == "logger" else ""
                raise ValueError(f"cannot {f.kind} {f.process!r}{why}: processes are {', '.join(names[1:])}")

    @property
    def process_faults(self) -> bool:
        return any(f.process is not None for f in self.sc.faults)

    def log_path(self, name: str) -> Path:
        return self.run_dir / "logs" / f"{name}.log"

    def make_folder(self) -> Path:
        """The run folder with logs/, stats/ and the scenario as run; that file."""
        self.run_dir.mkdir(parents=True, exist_ok=True)
        (self.run_dir / "logs").mkdir(exist_ok=True)
        (self.run_dir / "stats").mkdir(exist_ok=True)
        scenario_file = self.run_dir / "scenario.toml"
        scenario_file.write_text(scenario_files.dumps(self.sc.raw))
        return scenario_file

    def write_logins(
        self, *, world: str, host_logins: dict[str, trust.Credential] | None, tls: trust.Tls | None
    ) -> dict[str, Path]:
        """Fresh credentials for every process of the run (none without auth): user -> file."""
        if not self.options.auth:
            return {}
        return trust.write_run_secrets(
            self.run_dir / SECRETS,
            self.run_id,
            self.sc.robots,
            self.sc.leader.robot_id,
            world=world,
            host_logins=host_logins,
            tls=tls,
            observer=self.options.observer_login is not None,
            ros2=ros2_mod.access(self),
        )

    def command_lines(
        self, endpoint: str, secrets: Mapping[str, Path], *, remote_agents: bool, live: str | None
    ) -> dict[str, list[str]]:
        """name -> argv of each process started on this machine: the world, the
        logger, and the agents unless they run on hosts. With hosts the
        launcher is the router (it outlives the world: the hosts are reached
        through it until their agents' logs are fetched); else the world is."""
        lines = {"world": self._world(endpoint, secrets, remote_agents)}
        if self.options.logger:
            lines["logger"] = self._logger(endpoint, secrets, live)
        if self.bridge:
            lines[ros2_mod.BRIDGE] = ros2_mod.bridge_argv(self, endpoint, _auth(secrets, acl.BRIDGE))
        for rid in [] if remote_agents else self.own_robots:
            lines[f"agent-{rid}"] = self._agent(rid, endpoint, secrets)
        return sharing.group(lines, sharing.per_process(self.sc), self.run_dir / "control")

    def restart_argv(self, argv: Sequence[str], name: str) -> list[str]:
        """A fresh agent's command line: the first one's, with stats of its own."""
        out = list(argv)
        out[out.index("--stats") + 1] = str(self.run_dir / "stats" / f"{name}.json")
        if "--wire-spool" in out:
            out[out.index("--wire-spool") + 1] = str(spool_path(self.run_dir, name))
        return out

    def agent_request(self, name: str, scenario_text: str, logins: Mapping[str, Mapping[str, Any]]) -> HostRequest:
        """What a host is asked to start agent ``name`` (agent-3, agent-3.2) with,
        its login included (``logins``: user -> settings, the launcher's copy)."""
        rid = int(name.split(".")[0].removeprefix("agent-"))
        user, password = acl.agent_user(rid), ""
        if logins:
            password = logins[user]["transport/auth/usrpwd"]["password"]
        return HostRequest(
            "start",
            __version__,
            run=self.run_id,
            process=name,
            scenario=scenario_text,
            user=user,
            password=password,
            world_grace_s=AGENT_WORLD_GRACE_S,
            lockstep=self.options.mode == "lockstep",
        )

    # -- each role's command line ---------------------------------------------------
    def _py(self, module: str) -> list[str]:
        return [self.options.python, "-m", f"formation_swarm.{module}"]

    def _common(self) -> list[str]:
        wait = self.options.peers_timeout_s
        return [
            "--scenario",
            str(self.run_dir / "scenario.toml"),
            "--run",
            self.run_id,
            *(["--peers-timeout", f"{wait:g}"] if wait is not None else []),
        ]

    def _stats(self, name: str) -> str:
        return str(self.run_dir / "stats" / f"{name}.json")

    def _spool(self, name: str) -> list[str]:
        return ["--wire-spool", str(spool_path(self.run_dir, name))] if self.options.record_wire else []

    def _world(self, endpoint: str, secrets: Mapping[str, Path], remote_agents: bool) -> list[str]:
        opts = self.options
        zenoh_role = (
            ["--zenoh-mode", "client", "--connect", endpoint, *_auth(secrets, "world")]
            if remote_agents
            else ["--zenoh-mode", "router", "--listen", endpoint, *_auth(secrets, "router")]
        )
        return [
            *self._py("nodes.world.main"),
            *self._common(),
            "--mode",
            opts.mode,
            "--stats",
            self._stats("world"),
            *self._spool("world"),
            *zenoh_role,
            *["--expect-logger"] * opts.logger,
            *["--expect-bridge"] * self.bridge,
            *[arg for r in self.ros2_robots for arg in ("--ros2-robot", str(r))],
            *["--truth-every-tick"] * (bool(self.ros2_robots) and opts.mode == "lockstep"),
            *["--process-faults"] * self.process_faults,
            *(["--rt-priority", str(opts.rt_priority)] if opts.rt_priority is not None else []),
        ]

    def _logger(self, endpoint: str, secrets: Mapping[str, Path], live: str | None) -> list[str]:
        extra = ["--live", live] if live else []
        if self.options.serve_web:
            grpc, web = self.options.web_ports
            extra += ["--serve-web", "--grpc-port", str(grpc), "--web-port", str(web)]
        return [
            *self._py("nodes.logger.main"),
            *self._common(),
            "--out",
            str(self.run_dir / "recording.rrd"),
            *self._spool("logger"),
            "--stats",
            self._stats("logger"),
            "--connect",
            endpoint,
            *extra,
            *_auth(secrets, "logger"),
        ]

    def _agent(self, rid: int, endpoint: str, secrets: Mapping[str, Path]) -> list[str]:
        return [
            *self._py("nodes.agent.main"),
            "--id",
            str(rid),
            *self._common(),
            "--stats",
            self._stats(f"agent-{rid}"),
            *self._spool(f"agent-{rid}"),
            "--connect",
            endpoint,
            "--world-grace",
            f"{AGENT_WORLD_GRACE_S:g}",
            *(["--lockstep"] if self.options.mode == "lockstep" else []),
            *_auth(secrets, acl.agent_user(rid)),
        ]


def _auth(secrets: Mapping[str, Path], user: str) -> list[str]:
    # Each process deletes its login once read: nothing of the run's passwords stays on disk.
    return ["--auth", str(secrets[user]), "--auth-once"] if secrets else []
