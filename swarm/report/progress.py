"""Progress of swarm report, compare and export: a terse line on stderr as
each step starts ("report: figure 2/4 formation_error.png"), always, so a
long report is seen to work and a log of it says where it stopped."""

from __future__ import annotations

import sys
from collections.abc import Callable

Progress = Callable[[str], None]  # told each step as it starts


def say_progress(command: str) -> Progress:
    """Lines "``command``: step" on stderr, flushed at once."""
    return lambda line: print(f"{command}: {line}", file=sys.stderr, flush=True)


def quiet(_line: str) -> None:
    """No progress (the default of the library functions)."""
