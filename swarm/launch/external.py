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
fresh passwords: they are valid while the run lasts, and the copy of the
agent's login in the run folder goes with the run's other secrets.
"""

from __future__ import annotations

import json
import os
import shlex
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.protocol import acl, trust
from formation_swarm.runtime.children import log_tail
from formation_swarm.runtime.summary.end_reason import PEERS_TIMEOUT

if TYPE_CHECKING:
    from formation_swarm.launch.plan import Plan
    from formation_swarm.spec.scenario import Scenario


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
        "start it with (an agent of your own takes the same values):",
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
    return f"[swarm] the world gave up after{why}"


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
    and, in a follower's entry, ``"external": true``."""
    summary["external_robots"] = list(robots)
    followers = summary.get("followers") or {}
    for rid in robots:
        entry = followers.get(str(rid))
        if isinstance(entry, dict):
            entry["external"] = True


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
