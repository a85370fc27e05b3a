"""The logins of one run, as the launcher holds them: the files it wrote
(each process deletes its own once read, with ``--auth-once``; an outside
agent's goes once its agent is there, launch.external) and every login's
settings in memory, for a restarted agent, a host's agents and the
launcher's own session. And, at the end, the robots' logins that a second
session used (the world saw it: nodes.world.sessions)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.protocol import trust

if TYPE_CHECKING:
    from formation_swarm.launch.record import Journal

USED_TWICE = "robot login used twice"  # the launcher's event, one per second session the world saw


@dataclass
class RunLogins:
    files: dict[str, Path] = field(default_factory=dict)  # user -> the file written for it
    settings: dict[str, dict[str, Any]] = field(default_factory=dict)  # user -> its Zenoh settings

    @classmethod
    def kept(cls, files: Mapping[str, Path]) -> RunLogins:
        """The logins just written, read into memory."""
        return cls(dict(files), {user: trust.read_settings(path) for user, path in files.items()})

    def forget_unread(self, argvs: Iterable[list[str]], keep: Iterable[Path | None] = ()) -> None:
        """Delete the files no process started here reads (the hosts' agents',
        the launcher's), but those in ``keep`` (an outside agent's)."""
        lines, kept = list(argvs), set(keep)
        for path in self.files.values():
            if path not in kept and not any(str(path) in argv for argv in lines):
                path.unlink(missing_ok=True)

    def rewrite(self, user: str, argv: list[str]) -> None:
        """A restarted process's login file, fresh (the first one deleted its own)."""
        if "--auth" in argv:
            trust.write_settings(Path(argv[argv.index("--auth") + 1]), self.settings[user])


def say_second_sessions(world: Mapping[str, Any], journal: Journal) -> None:
    """Each robot whose login a second session used, as the world saw it: a
    second agent's answers refused (its stats' ``duplicate_agents``), or its
    token kept after the agent's session closed (``second_sessions``). An
    event each, and a warning on the console."""
    dups = world.get("duplicate_agents")
    for rid, refused in sorted(dups.items()) if isinstance(dups, Mapping) else []:
        if str(rid).isdigit() and isinstance(refused, int) and refused > 0:
            login = f"agent-{rid}"
            journal.add(USED_TWICE, robot=int(rid), login=login, answers_refused=refused)
            journal.say(
                f"[swarm] warning: robot {rid}'s login {login} answered from two sessions during the run ({refused} "
                "answers refused): a second agent flew beside its own; the login file was stolen or the agent "
                "started twice"
            )
    records = world.get("second_sessions")
    for rec in records if isinstance(records, list) else []:
        if not isinstance(rec, Mapping) or not isinstance(rid := rec.get("robot"), int):
            continue
        t, login = rec.get("time_s"), rec.get("login")
        journal.add(USED_TWICE, robot=rid, login=login, kept_token=True, tick=rec.get("tick"), sim_time_s=t)
        when = f"at sim t={t:.2f} s" if isinstance(t, (int, float)) else "during the run"
        journal.say(
            f"[swarm] warning: robot {rid}'s login {login} was used by a second session: it kept the robot's token "
            f"after its agent's session closed {when}; the robot was counted lost, not flown by it; the login "
            "file was stolen or its agent started twice"
        )
