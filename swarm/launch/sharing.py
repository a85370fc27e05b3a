"""Robots that share a process (``run.agents_per_process`` = K above 1): the
run's agents' command lines grouped K by K into nodes.agent.shared's, and the
calls by which the launcher kills, freezes and thaws one robot of such a
process (a signal would act on all K), in RUN_DIR/control/, made at the first call."""

from __future__ import annotations

import signal
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

MODULE = "formation_swarm.nodes.agent.shared"
AGENT_MODULE = "formation_swarm.nodes.agent.main"
SEPARATOR = "--"  # between the robots' command lines (nodes.agent.shared)
CALL_SIGNAL = signal.SIGUSR1  # wakes a shared process to read its calls at once (nodes.agent.shared)


def per_process(sc: Scenario) -> int:
    """The scenario's ``run.agents_per_process`` (checked by its loader; 1 when not given)."""
    return int(sc.raw.get("run", {}).get("agents_per_process", 1))


def group(lines: Mapping[str, list[str]], k: int, control_dir: Path) -> dict[str, list[str]]:
    """``lines`` (name -> argv) with the agents' taken K by K, in robot order,
    into one process each, named after its robots (agents-2-11); the rest as given."""
    if k <= 1:
        return dict(lines)
    agents = [name for name in lines if name.startswith("agent-")]
    out = {name: argv for name, argv in lines.items() if name not in agents}
    for i in range(0, len(agents), k):
        names = agents[i : i + k]
        first, last = names[0].removeprefix("agent-"), names[-1].removeprefix("agent-")
        shared = f"agents-{first}" if first == last else f"agents-{first}-{last}"
        argv = [*lines[names[0]][:2], MODULE, "--control", str(control_dir / f"{shared}.calls")]
        for name in names:
            argv += [SEPARATOR, *lines[name][3:]]
        out[shared] = argv
    return out


def robots_in(argv: Sequence[str]) -> dict[str, list[str]]:
    """A shared process's robots: agent-N -> that robot's own ``swarm agent``
    command line (empty for any other process's argv)."""
    if len(argv) < 3 or argv[2] != MODULE:
        return {}
    out: dict[str, list[str]] = {}
    own: list[str] | None = None
    for arg in [*argv[3:], SEPARATOR]:
        if arg != SEPARATOR:
            if own is not None:
                own.append(arg)
            continue
        if own:
            out[f"agent-{own[own.index('--id') + 1]}"] = [*argv[:2], AGENT_MODULE, *own]
        own = []
    return out


def control_path(argv: Sequence[str]) -> Path:
    return Path(argv[list(argv).index("--control") + 1])


class Control:
    """The launcher's calls to one shared process, appended to its control
    file; ``wake`` (its process's CALL_SIGNAL) after each, so it reads them at once."""

    def __init__(self, path: Path, wake: Callable[[], None] | None = None) -> None:
        self.path = path
        self.seq = 0
        self.wake = wake

    def call(self, action: str, process: str) -> None:
        """``action`` (kill, freeze, thaw) on robot ``process`` (agent-N)."""
        self.seq += 1
        self.path.parent.mkdir(exist_ok=True)  # at the first call: a run without one has no control/
        with self.path.open("a", encoding="utf-8") as f:
            f.write(f"{self.seq} {action} {process.removeprefix('agent-')}\n")
        if self.wake is not None:
            self.wake()
