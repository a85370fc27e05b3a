"""A run's agents on other machines (``swarm run --hosts a,b``), each started
by that machine's ``swarm host`` (formation_swarm.nodes.host.main).

The world listens on ``listen``, an address the hosts reach, and is their
router. The launcher waits (with a deadline) for each host's token, checks
its version and the robots it may run, places the robots (``placement``, the
others round-robin), and starts them there; process faults on a remote agent
are executed by its host. At the end it fetches each remote agent's log and
stats into logs/ and stats/, and the summary says where each agent ran. A
host that goes mid-run has its robots counted dead, and the run fails naming it.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

from formation_swarm.common.version import __version__
from formation_swarm.launch import remote
from formation_swarm.launch.plan import SECRETS, Plan
from formation_swarm.launch.processes import Processes
from formation_swarm.launch.record import Journal
from formation_swarm.protocol import trust
from formation_swarm.protocol.hostmsg import HostReply, HostRequest
from formation_swarm.protocol.keys import check_host_name
from formation_swarm.protocol.session import listen_problem, loopback, make_config


@dataclass(frozen=True, kw_only=True)
class HostOptions:
    """The keywords of :class:`~formation_swarm.launch.launcher.Launch` for
    agents on other machines, with their defaults (none: everything here)."""

    hosts: Sequence[str] = ()
    placement: Mapping[int, str] | None = None  # robot -> host, over the scenario's [placement]
    listen: str | None = None  # where the run's router listens for the hosts
    host_logins: str | Path | None = None  # hosts.txt of swarm secure --hosts
    hosts_timeout_s: float = 30.0  # the wait for every host to connect
    tls: trust.Tls | None = None  # the router's TLS identity on listen (its local endpoint stays on loopback)


def _names(hosts: Sequence[str]) -> list[str]:
    names = [check_host_name(h) for h in hosts]
    if len(set(names)) != len(names):
        raise ValueError(f"--hosts names a host twice: {','.join(names)}")
    return names


def _explicit(names: Sequence[str], plan: Plan, placement: Mapping[int, str] | None) -> dict[int, str]:
    """The scenario's [placement], then --place; a run on this machine alone ignores both."""
    explicit = {**dict(plan.sc.placement), **dict(placement or {})} if names else {}
    if placement and not names:
        raise ValueError("a placement needs --hosts")
    for rid, h in explicit.items():
        if rid not in plan.sc.robots:
            robots = ", ".join(map(str, plan.sc.robots))
            raise ValueError(f"placement {rid}={h}: no robot {rid}; robots are {robots}")
        if h not in names:
            raise ValueError(f"placement {rid}={h}: {h} is not one of --hosts {','.join(names)}")
    return explicit


def _check_listen(names: Sequence[str], listen: str | None) -> None:
    if names and not listen:
        raise ValueError(
            "--hosts needs --listen ENDPOINT: where the launcher, the run's router, listens for the hosts, "
            "e.g. tcp/192.168.1.10:7447 (an address every host reaches)"
        )
    if names and listen:  # checked before anything starts: a run that cannot listen fails a bad command
        try:
            why = listen_problem(listen)
        except ValueError as exc:
            raise ValueError(f"--listen {listen}: {exc}") from None
        if why is not None:
            raise ValueError(
                f"--listen {listen}: cannot listen there ({why}); give a free port of an address of this machine"
            )


def _check_tls(names: Sequence[str], auth: bool, listen: str | None, tls: trust.Tls | None) -> None:
    if tls is not None and not (names and auth and listen and listen.startswith("tls/")):
        raise ValueError("TLS files are for --hosts with --listen tls/ADDRESS:PORT and logins")
    if names and listen and listen.startswith("tls/") and tls is None:
        raise ValueError(
            f"--listen {listen}: a TLS router needs --tls-ca, --tls-cert and --tls-key (the CA the "
            "hosts trust, this router's certificate and key)"
        )


class Hosts:
    """The run's hosts: checked when the run is made, their agents started
    with the run, watched while it goes, their logs fetched at its end."""

    def __init__(self, options: HostOptions, plan: Plan, journal: Journal, procs: Processes) -> None:
        self.names = _names(options.hosts)
        self.explicit = _explicit(self.names, plan, options.placement)
        self.listen = options.listen
        _check_listen(self.names, self.listen)
        _check_tls(self.names, plan.options.auth, self.listen, options.tls)
        self.tls = options.tls
        if self.names and self.listen and self.listen.startswith("tcp/") and not loopback(self.listen):
            journal.say(
                f"[swarm] warning: --listen {self.listen} is plain TCP: the hosts get their agents' passwords, "
                "and the run's data crosses the network, unencrypted (deploy/README.md: TLS)"
            )
        self.logins: dict[str, trust.Credential] | None = None
        # Where swarm secure --hosts wrote each host's login: beside --host-logins.
        self.logins_dir = Path(options.host_logins).parent if options.host_logins is not None else None
        if self.names and plan.options.auth:
            if options.host_logins is None:
                raise ValueError(
                    "--hosts needs --host-logins FILE: the hosts' logins the run's router lets in "
                    "(swarm secure --hosts NAMES writes it)"
                )
            self.logins = trust.read_host_logins(options.host_logins, self.names)
        self.timeout_s = options.hosts_timeout_s
        self.plan, self.journal, self.procs = plan, journal, procs
        self.clients: dict[str, remote.HostClient] = {}
        self.poller: remote.Poller | None = None
        self.placement: dict[int, str] = {}
        self.infos: dict[str, HostReply] = {}
        self.lost: list[str] = []
        self.left_out: dict[str, str] = {}  # host -> why it is not used (remote.HostLoginTwice)
        self.rejected: dict[str, dict[str, int]] = {}  # per host, the answers refused (remote.HostClient.ask)
        self.run_logins: Mapping[str, Mapping[str, Any]] = {}  # user -> settings: the agents' for their hosts

    def open_router(self, endpoint: str, secrets: Mapping[str, Path]) -> zenoh.Session:
        """The launcher's session, the run's router: on ``listen`` for the
        hosts and on ``endpoint`` for this machine's processes."""
        assert self.listen is not None
        settings = trust.read_settings(secrets["router"]) if secrets else None
        session = zenoh.open(make_config("router", listen=[self.listen, endpoint], settings=settings))
        trust.forget_router_secrets(self.plan.run_dir / SECRETS)  # read: the hosts' lasting logins leave the disk
        return session

    def start(self, session: zenoh.Session, logins: Mapping[str, Mapping[str, Any]]) -> None:
        """Wait for the hosts, check them, place the robots, start their agents."""
        self.run_logins = logins  # kept: a restarted agent's login comes from here
        self.clients = {h: remote.HostClient(session, h) for h in self.names}
        self._wait_for_hosts()
        usable = self._leave_out_doubled()
        allowed = {h: info.robots for h, info in self.infos.items()}
        self.placement = remote.place(self.plan.sc.robots, usable, allowed, self.explicit)
        if idle := [h for h in usable if h not in self.placement.values()]:
            self.journal.say(
                f"[swarm] warning: host{'s' if len(idle) > 1 else ''} {', '.join(idle)} "
                f"run{'' if len(idle) > 1 else 's'} no robot (the placement gave them none)"
            )
        scenario_text = (self.plan.run_dir / "scenario.toml").read_text()
        for rid, h in self.placement.items():
            self.journal.say(f"[swarm] agent-{rid} on host {h}")
            self.start_agent(f"agent-{rid}", h, scenario_text, logins)
        self.poller = remote.Poller(list(self.clients.values()), self.plan.run_id)

    def _wait_for_hosts(self) -> None:
        """Each host's token, within the deadline, and what it says of itself."""
        deadline = time.monotonic() + self.timeout_s
        if not all(c.present.wait(0.2) for c in self.clients.values()):  # said only if it takes a while
            missing = [h for h, c in self.clients.items() if not c.present.is_set()]
            self.journal.say(
                f"[swarm] waiting up to {self.timeout_s:g} s for host{'s' if len(missing) > 1 else ''} "
                f"{', '.join(missing)} to connect to {self.listen}"
            )
        for h, client in self.clients.items():
            if not client.present.wait(max(0.0, deadline - time.monotonic())):
                login = self.logins_dir / f"host-{h}.json" if self.logins_dir is not None else f"host-{h}.json"
                raise remote.HostError(
                    f"host {h} did not connect to {self.listen} within {self.timeout_s:g} s: start "
                    f"'swarm host --connect <this address> --name {h} --auth {login}' there (that file copied "
                    "to its machine), and check its --connect, its login and the network"
                )
            try:
                client.info = self.infos[h] = client.ask(HostRequest("info", __version__))
            except remote.HostLoginTwice as exc:
                self.left_out[h] = str(exc)

    def _leave_out_doubled(self) -> list[str]:
        """The hosts the run may use: not one whose login answered from two
        sessions (neither can be told to be the host, so neither is sent an
        agent's login); its robots go to the others, unless placed on it or
        no other host is left (HostError)."""
        for h, why in self.left_out.items():
            self.clients.pop(h).close()
            self.journal.add("host left out", host=h, why=why, wall_s=self.journal.wall_s())
            self.journal.say(f"[swarm] warning: {why}; host {h} is left out of this run")
        usable = [h for h in self.names if h not in self.left_out]
        pinned = sorted(r for r, h in self.explicit.items() if h in self.left_out)
        if self.left_out and (pinned or not usable):
            on = f"robots {', '.join(map(str, pinned))} are placed on it" if pinned else "no other host is left"
            raise remote.HostError(f"{next(iter(self.left_out.values()))}; {on}")
        return usable

    def start_agent(self, name: str, host: str, scenario_text: str, logins: Mapping[str, Mapping[str, Any]]) -> str:
        """Agent ``name`` (agent-3, or a fresh one: agent-3.2) started on ``host``; its name."""
        req = self.plan.agent_request(name, scenario_text, logins)
        child = remote.RemoteChild(
            name, [], self.plan.log_path(name), client=self.clients[host], run=self.plan.run_id, request=req
        )
        return self.procs.start(child)

    def restart(self, old: remote.RemoteChild, name: str) -> str:
        """A fresh agent ``name`` on the host of ``old`` (killed and reaped by now)."""
        scenario_text = (self.plan.run_dir / "scenario.toml").read_text()
        return self.start_agent(name, old.host, scenario_text, self.run_logins)

    def check_lost(self, t: float) -> None:
        """A host whose token went: an event and a line, once; its robots count dead."""
        for h, client in self.clients.items():
            if client.lost and not client.reported:
                client.reported = True
                self.lost.append(h)
                robots = [r for r, ph in self.placement.items() if ph == h]
                self.journal.add("host lost", host=h, robots=robots, sim_time_s=t, wall_s=self.journal.wall_s())
                wall = self.journal.wall_s()
                dead = f"robot{'s' if len(robots) > 1 else ''} {', '.join(map(str, robots))}" if robots else "none"
                self.journal.say(
                    f"[swarm] host {h} was lost {wall:.1f} s of wall time into the run (its token went): "
                    f"{dead} counted dead"
                )

    def say_lost(self) -> None:
        for h in self.lost:
            robots = ", ".join(str(r) for r, ph in self.placement.items() if ph == h)
            self.journal.say(f"[swarm] the run failed: host {h} was lost; its robots ({robots}) were counted dead")

    def stop(self) -> None:
        """Fetch the remote agents' logs and stats, end the run on every host."""
        if not self.clients:
            return
        if self.poller is not None:
            self.poller.close()
            self.poller = None
        stats = self.plan.run_dir / "stats"
        for c in self.procs.children.values():
            if isinstance(c, remote.RemoteChild) and (why := c.fetch(stats)) is not None:
                self.journal.add("not fetched", process=c.name, host=c.host, why=why)
        for h, client in self.clients.items():
            if not client.lost:
                with contextlib.suppress(remote.HostError):
                    client.ask(HostRequest("end", __version__, run=self.plan.run_id))
            client.close()
            self.rejected[h] = dict(client.rejections.by_reason)
            self._say_doubled(h)
        self.clients = {}

    def _say_doubled(self, h: str) -> None:
        """Host ``h``'s login, answering from another session during the run: said."""
        if not (refused := self.rejected[h].get(remote.ANOTHER_SESSION, 0)):
            return
        self.journal.add("host login used twice", host=h, answers_refused=refused, wall_s=self.journal.wall_s())
        self.journal.say(
            f"[swarm] warning: host {h}'s login answered from another session too during the run ({refused} "
            f"answers refused): that session heard the run's requests to host {h}, its agents' logins included; "
            "make new host logins (swarm secure --hosts) and restart the hosts with them"
        )

    def add_to_summary(self, summary: dict[str, Any]) -> None:
        """Where each agent ran, and what each host said of itself."""
        if not self.names:
            return
        summary["placement"] = {f"agent-{r}": h for r, h in self.placement.items()}
        summary["hosts"] = {
            h: {
                "hostname": i.hostname,
                "cores": i.cores,
                "free_mem_mb": i.free_mem_mb,
                "version": i.version,
                "lost": h in self.lost,
                # answers refused: undecodable, another host's, another session's on this host's login
                "rejected": self.rejected.get(h, {}),
            }
            for h, i in self.infos.items()
        }
        for name, proc in summary.get("processes", {}).items():
            child = self.procs.children.get(name)
            proc["host"] = child.host if isinstance(child, remote.RemoteChild) else "local"
