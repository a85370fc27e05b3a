"""The faults the engine takes: every link, network, sensor and actuator
fault (the link layer and the world do them, as in a distributed run), and
the process faults it can carry out itself on an agent (restart, freeze).
A fault that needs a process of its own is refused, in one line."""

from __future__ import annotations

from collections.abc import Iterable

from formation_swarm.common.faults import Fault


def refusal(fault: Fault) -> str | None:
    """Why the engine cannot do ``fault``, in one line (None: it can)."""
    if fault.kind == "kill":
        return (
            f"fault '{fault}': a kill is a SIGKILL of a process and the engine runs every robot in this one; "
            "swarm run does it (restart and freeze run here)"
        )
    if fault.process == "logger":
        return f"fault '{fault}': the engine has no logger process (it records nothing); swarm run has one"
    return None


def check(faults: Iterable[Fault]) -> None:
    """ValueError for the first fault the engine cannot do."""
    for fault in faults:
        if (why := refusal(fault)) is not None:
            raise ValueError(why)
