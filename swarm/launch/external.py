"""Robots left to an agent the launcher does not start, and the read-only login.

``swarm run S --external 3`` starts every process of the run but robot 3's
agent. The run's router (the world) lets in robot 3's login as for any agent,
the world waits for its token before tick 0 (``--peers-timeout``) and lockstep
waits for its answers as for any agent's. The launcher says on its console the
one command line that starts such an agent: our ``swarm agent`` with the
run's endpoint, run id, login file and scenario file; an agent of one's own
takes the same four values (docs/protocol/outside-agents.md, "Joining a run
from outside").

``swarm run S --observer-login FILE`` lets in the ``observer`` login too (it
hears the whole run and can send nothing: protocol.trust) and writes it to
FILE for a dashboard or a monitor of one's own. Both logins hold the run's
fresh passwords: they are valid while the run lasts.

An outside agent's login file goes once its agent is there, as every other
process's (:class:`Outside`): the launcher deletes it when the robot's token
comes, and writes it again when the token goes during the run, for a fresh
agent. An outside agent lost during the run is said and counted as any
agent's: the world's ``deaths``, an event ``outside agent left``.
"""

from __future__ import annotations

import json
import os
import queue
import shlex
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import zenoh

from formation_swarm.launch.logins import USED_TWICE, say_second_sessions
from formation_swarm.protocol import acl, trust
from formation_swarm.protocol.keys import Keys
from formation_swarm.runtime.children import log_tail
from formation_swarm.runtime.summary.end_reason import PEERS_TIMEOUT

if TYPE_CHECKING:
    from formation_swarm.launch.plan import Plan
    from formation_swarm.launch.record import Journal, StatusFeed
    from formation_swarm.spec.scenario import Scenario

CONNECTED, LEFT = "outside agent connected", "outside agent left"  # the launcher's events


@dataclass(frozen=True)
class ExternalAgent:
    """What an outside agent needs to fly ``robot`` in a run."""

    robot: int
    endpoint: str  # the run's router, e.g. tcp/127.0.0.1:40123
    run_id: str
    scenario: Path  # the scenario as run
    login: Path | None  # its login (Zenoh settings, JSON); None in a run without authentication

    def flags(self) -> list[str]:
        """``--id N --scenario FILE --run ID --connect ENDPOINT [--auth FILE]``."""
        out = ["--id", str(self.robot), "--scenario", str(self.scenario), "--run", self.run_id]
        out += ["--connect", self.endpoint]
        return out + (["--auth", str(self.login)] if self.login is not None else [])

    def command_line(self) -> str:
        """The one command line that starts our agent for this robot (a shell's words)."""
        return shlex.join(["swarm", "agent", *self.flags()])


def check(sc: Scenario, external: Sequence[int | str] | int | str) -> tuple[int, ...]:
    """The robots left to outside agents, checked against the scenario (ValueError
    naming the problem): robots of the run, each once, with no process fault on
    their agent (the launcher could not execute it)."""
    if isinstance(external, (int, str)):
        external = [external]  # one given alone
    out: list[int] = []
    for value in external:
        rid = value
        if isinstance(value, str) and value.strip().isdigit():
            rid = int(value)
        if isinstance(rid, bool) or not isinstance(rid, int) or rid not in sc.robots:
            robots = ", ".join(map(str, sc.robots))
            raise ValueError(f"external: {value!r} is not a robot of {sc.name}; its robots are {robots}")
        if rid in out:
            raise ValueError(f"external: robot {rid} is named twice")
        out.append(rid)
    mine = {f"agent-{r}" for r in out}
    if faulted := sorted({f.process for f in sc.faults if f.process in mine}):
        raise ValueError(
            f"cannot execute a process fault on {', '.join(faulted)}: it is external, started by someone "
            "else; the launcher kills, restarts and freezes only the agents it starts"
        )
    return tuple(out)


def slots(
    robots: Sequence[int], *, endpoint: str, run_id: str, scenario: Path, logins: Mapping[str, Path]
) -> dict[int, ExternalAgent]:
    """What each outside agent needs, by robot (its login from the run's secrets)."""
    return {
        rid: ExternalAgent(
            robot=rid,
            endpoint=endpoint,
            run_id=run_id,
            scenario=scenario,
            login=logins.get(acl.agent_user(rid)),
        )
        for rid in robots
    }


def announce(agent: ExternalAgent, wait_s: float) -> list[str]:
    """The console lines that hand a robot to its outside agent."""
    return [
        f"[swarm] robot {agent.robot} is left to an outside agent: the world waits up to {wait_s:g} s for it; "
        "start it with (an agent of your own takes the same values; the login file goes once it is connected):",
        f"  {agent.command_line()}",
    ]


def gave_up(world: Mapping[str, Any], events: Sequence[Mapping[str, Any]], plan: Plan) -> str | None:
    """What the world waited for in vain before tick 0 (an outside agent that
    never came, say), from its log, for the console; None when the world did
    not give up, or its exit was said already (an agent's exit that followed
    it may have been said instead)."""
    if world.get("end_reason") != PEERS_TIMEOUT or any(e.get("process") == "world" for e in events):
        return None
    log = plan.log_path("world")
    said = [line for line in log_tail(log, lines=40) if "gave up after" in line]
    why = said[-1].split("gave up after", 1)[1] if said else f" its wait: see {log}"
    if (outside := never_came(world, plan.external)) is not None:
        return f"[swarm] {outside}"
    return f"[swarm] the world gave up after{why}"


@dataclass
class Outside:
    """The launcher's watch over the outside agents, from their tokens: each
    one's login file deleted once its agent is there, written again when it
    leaves during the run (for a fresh one), and each loss said."""

    agents: Mapping[int, ExternalAgent]
    settings: Mapping[str, Mapping[str, Any]]  # user -> its login, from the launcher's memory
    journal: Journal
    keys: Keys
    changes: queue.SimpleQueue[tuple[int, bool]] = field(default_factory=queue.SimpleQueue)

    def listen(self, session: zenoh.Session) -> None:
        if self.agents:
            session.liveliness().declare_subscriber(self.keys.alive_all("agent"), self._token, history=True)

    def _token(self, sample: zenoh.Sample) -> None:  # a Zenoh thread: hands over only
        parsed = self.keys.parse_alive(str(sample.key_expr))
        if parsed is not None and parsed[1].isdigit() and int(parsed[1]) in self.agents:
            self.changes.put((int(parsed[1]), sample.kind == zenoh.SampleKind.PUT))

    def look(self, status: StatusFeed) -> None:
        """The tokens that came or went since the last look (``status``: the world's, read first)."""
        t = status.sim_time()
        while not self.changes.empty():
            rid, present = self.changes.get()
            agent, wall = self.agents[rid], round(self.journal.wall_s(), 3)
            if present and agent.login is not None and agent.login.exists():
                agent.login.unlink(missing_ok=True)  # read by now: its session is open
                self.journal.add(CONNECTED, robot=rid, sim_time_s=t, wall_s=wall)
                self.journal.say(f"[swarm] robot {rid}'s outside agent connected: its login file is deleted")
            elif not present and not status.done:
                again = "" if agent.login is None else self._write_again(agent.login, rid)
                # The launcher hears the token go after the world has; the summary places it at the world's tick.
                when = (
                    f"noticed at sim t={t:.2f} s; the summary gives the world's tick"
                    if t >= 0
                    else "before the run started"
                )
                self.journal.add(LEFT, robot=rid, sim_time_s=t, wall_s=wall)
                self.journal.say(f"[swarm] robot {rid}'s outside agent left ({when}): its token went{again}")

    def _write_again(self, login: Path, rid: int) -> str:
        """Robot ``rid``'s login file written again, for a fresh agent; said how."""
        try:
            trust.write_settings(login, self.settings[acl.agent_user(rid)])
        except OSError as exc:  # the run folder gone or full: the run goes on without it
            return f"; its login could not be written again ({exc.strerror or exc})"
        return f"; its login is written again for a fresh agent: {login}"

    def settle(self, world: Mapping[str, Any]) -> None:
        """At the end: each loss placed at the tick the world saw it; one the
        tokens did not show (a second session on its login kept the token)
        added; and every robot's login a second session used, said."""
        say_second_sessions(world, self.journal)
        said = {
            rid: [e for e in self.journal.events if e.get("event") == LEFT and e.get("robot") == rid]
            for rid in self.agents
        }
        for d in world.get("deaths") or []:
            rid = d.get("robot") if isinstance(d, Mapping) and d.get("cause") == "lost" else None
            if rid not in said:
                continue
            at = {"tick": d.get("tick"), "sim_time_s": d.get("time_s"), "placed_by": "the world"}
            if said[rid]:
                said[rid].pop(0).update(at)
                continue
            self.journal.add(LEFT, robot=rid, **at)
            when = f"sim t={at['sim_time_s']:.2f} s" if isinstance(at["sim_time_s"], (int, float)) else "during the run"
            kept = any(
                e.get("event") == USED_TWICE and e.get("robot") == rid and e.get("kept_token")
                for e in self.journal.events
            )
            how = "while a second session on its login kept its token" if kept else "(the world saw it)"
            self.journal.say(
                f"[swarm] robot {rid}'s outside agent left at {when}: its session closed {how}; the world counted "
                "the robot's agent lost"
            )


def write_observer_login(source: Path, target: Path) -> Path:
    """A copy of the run's observer login at ``target`` (0600), with the files it
    names (the TLS CA) made absolute: it is read from elsewhere. An existing
    regular file is replaced (an earlier run's login, dead with that run)."""
    settings: dict[str, Any] = trust.read_settings(source)  # the CA, if any, made absolute
    target.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(json.dumps(settings, indent=1))
    os.chmod(target, 0o600)
    return target


def mark_summary(summary: dict[str, Any], robots: Sequence[int]) -> None:
    """The summary says which robots outside agents flew: ``external_robots``
    and, in a follower's entry, ``"external": true``; and, when the world gave
    up waiting for one, ``ended`` names it."""
    summary["external_robots"] = list(robots)
    followers = summary.get("followers") or {}
    for rid in robots:
        entry = followers.get(str(rid))
        if isinstance(entry, dict):
            entry["external"] = True
    if summary.get("end_reason") == PEERS_TIMEOUT and (
        said := never_came(summary.get("parts", {}).get("world", {}), robots)
    ):
        summary["ended"] = said


def never_came(world: Mapping[str, Any], robots: Sequence[int]) -> str | None:
    """The outside agents the world gave up waiting for before tick 0, in
    words, with its deadline; None if it waited for none."""
    waited = world.get("waited_for")
    if not isinstance(waited, Mapping):
        return None
    absent, t = waited.get("robots"), waited.get("timeout_s")
    missing = [r for r in absent if r in robots] if isinstance(absent, list) else []
    if not missing or not isinstance(t, (int, float)):
        return None
    who = f"robot{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))}"
    return (
        f"the outside agent of {who} (swarm run --external) never connected: the world gave up waiting "
        f"after {t:g} s (--peers-timeout); it waited for: {waited.get('missing')}"
    )


def hand_over(
    say: Callable[[str], None],
    agents: Mapping[int, ExternalAgent],
    wait_s: float,
    *,
    endpoint: str,
    observer_login: str | Path | None,
    run_id: str,
) -> None:
    """Say on the console how to join: each outside agent's command line, the observer's login."""
    for agent in agents.values():
        for line in announce(agent, wait_s):
            say(line)
    if observer_login is not None:
        say(
            f"[swarm] observer: --connect {endpoint} --auth {observer_login}: it hears the whole "
            f"run (swarm/{run_id}/**) and can send nothing"
        )
