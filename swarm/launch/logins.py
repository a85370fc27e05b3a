"""The logins of one run, as the launcher holds them: the files it wrote
(each process deletes its own once read, with ``--auth-once``) and every
login's settings in memory, for a restarted agent, a host's agents and the
launcher's own session."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from formation_swarm.protocol import trust


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
