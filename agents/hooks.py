"""The optional hooks of a follower's controller and of the leader's policy,
and their failures as a role records them (docs/controllers.md).

``reset()``, if the class has it, is called once before its first step:
when its agent builds it (nodes.agent.setup), at the start of a run, at an
agent's restart and at the engine's reset. ``close()``, if it has it, is
called once when its agent stops: the run's end, a stop signal, the engine's
run ended, reset or closed. A failure of a step or of either hook is a
record for the agent's stats (``controller_failure``: tick, error, law) and
a note, with its traceback, for the process's log.
"""

from __future__ import annotations

import traceback
from collections.abc import Callable
from typing import Any


def reset(obj: object) -> None:
    """``obj.reset()`` if it has one; what it raises is the caller's to report."""
    hook = bound(obj, "reset")
    if hook is not None:
        hook()


def bound(obj: object, name: str) -> Callable[[], object] | None:
    """``obj``'s optional hook ``name``, bound (a role binds it when it is
    built, as a wrapper put around the object later may not pass it on)."""
    hook = getattr(obj, name, None)
    return hook if callable(hook) else None


def failure(tick: int, exc: BaseException, law: str, robot_id: int) -> tuple[dict[str, Any], str]:
    """A step that raised at ``tick``: the stats' record and the log's note."""
    error = _error(exc)
    note = f"controller {law} failed at tick {tick}: {error}; robot {robot_id} stops for the rest of the run"
    return {"tick": tick, "error": error, "law": law}, f"{note}\n{_trace(exc)}"


def close(hook: Callable[[], object] | None, law: str, tick: int) -> tuple[dict[str, Any], str] | None:
    """Call a ``close`` hook (:func:`bound`; None: none), after ``tick`` (the
    last answered); None, or what it raised as the stats' record and the log's
    note: one line, the run's result kept, not a traceback that ends the process."""
    if hook is None:
        return None
    try:
        hook()
    except Exception as exc:  # noqa: BLE001 - a user's class: its failure is reported, the run's result kept
        error = f"close() raised {_error(exc)}"
        note = f"controller {law} failed after tick {tick}: {error}\n{_trace(exc)}"
        return {"tick": tick, "error": error, "law": law}, note
    return None


def _error(exc: BaseException) -> str:
    return " ".join(f"{type(exc).__name__}: {exc}".split())[:300]


def _trace(exc: BaseException) -> str:
    return "".join(traceback.format_exception(exc)).rstrip()
