"""Where a follower's control law or the leader's policy comes from when it
is not built in, and what parameters it declares.

``controller.law`` names a law one of three ways (docs/controllers.md):

- a built-in law, "fuzzy" or "lpsi" (agents.follower.BUILT_IN): always
  these, whatever is installed;
- ``"package.module:Class"``: a class imported from the Python path of the
  process that loads the scenario (the launcher, then each agent);
- another short name: an entry point of the group ``formation_swarm.controllers``
  (``importlib.metadata``) whose value is ``"package.module:Class"``.

``leader.policy`` names the leader's policy the same ways (:data:`LEADER`):
"path", the paper's (agents.leader_policy.PathLeader), ``module:Class``, or
an entry point of the group ``formation_swarm.leader_policies``.

A class declares its parameters in a class attribute ``PARAMS``, a mapping
of name -> default (a number, a boolean or a string); the scenario's
``[controller.params]`` (``[leader.params]``) gives values over them
(checked in spec.controllers). A class without ``PARAMS`` takes none.

Every error is one :class:`LawError` line naming the law and what is wrong.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.metadata
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from formation_swarm.agents.params import LAWS

ENTRY_POINT_GROUP = "formation_swarm.controllers"
POLICY_GROUP = "formation_swarm.leader_policies"
PATH = "path"  # the paper's leader policy (agents.leader_policy.PathLeader), the default
POLICIES = (PATH,)  # the built-in leader policies
_REFERENCE = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*")


@dataclass(frozen=True)
class Kind:
    """What a class is looked up for: a follower's law or the leader's policy."""

    word: str  # what the errors call its name: "law", "policy"
    group: str  # the entry points' group
    built_in: tuple[str, ...]  # the names that are always the package's own
    needs: str  # what its class must have, in words


FOLLOWER = Kind("law", ENTRY_POINT_GROUP, LAWS, "a follower controller needs step(FollowerInput) -> FollowerOutput")
LEADER = Kind("policy", POLICY_GROUP, POLICIES, "a leader's policy needs step(LeaderSensing | None) -> LeaderMove")


class LawError(ValueError):
    """A law that cannot be flown: no such module, class or entry point, or a
    class that is not a follower controller. The message is one line."""


def find_class(law: str, kind: Kind = FOLLOWER) -> type:
    """The class of a law (a policy) that is not built in: ``module:Class``
    or the name of an entry point of ``kind.group``."""
    if ":" in law:
        return _imported(law, law, kind)
    return _entry_point(law, kind)


def _imported(reference: str, law: str, kind: Kind) -> type:
    """The class ``reference`` ("module:Class") names."""
    if not _REFERENCE.fullmatch(reference):
        raise LawError(f"{law!r} is not module:Class (a dotted module name, a colon, a class name)")
    module_name, _, class_name = reference.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        missing = exc.name or module_name
        what = f"no module named {missing!r}" + ("" if missing == module_name else f" (imported by {module_name!r})")
        raise LawError(
            f"cannot import {module_name!r} for {kind.word} {law!r}: {what}; is it installed or on PYTHONPATH?"
        ) from None
    except Exception as exc:  # noqa: BLE001 - whatever a user's module raises on import is reported, in one line
        raise LawError(f"importing {module_name!r} for {kind.word} {law!r} raised {_one_line(exc)}") from None
    cls = getattr(module, class_name, None)
    if cls is None:
        found = [n for n in dir(module) if isinstance(getattr(module, n), type) and not n.startswith("_")]
        raise LawError(f"module {module_name!r} has no class {class_name!r}" + _close(class_name, found))
    return check_class(cls, law, kind)


def check_class(cls: Any, law: str, kind: Kind = FOLLOWER) -> type:
    """``cls`` if it is a class with ``step`` (a follower controller, a leader's policy)."""
    if not isinstance(cls, type):
        raise LawError(f"{law!r} is not a class but {type(cls).__name__} {cls!r:.60}")
    if not callable(getattr(cls, "step", None)):
        raise LawError(
            f"class {cls.__qualname__} of {kind.word} {law!r} has no step method: {kind.needs} (docs/controllers.md)"
        )
    declared_params(cls, law, kind)  # a bad PARAMS is the class's error, said now
    return cls


def _entry_point(name: str, kind: Kind) -> type:
    """The class registered as ``name`` in ``kind.group``."""
    points = importlib.metadata.entry_points(group=kind.group)
    found = {ep.value for ep in points if ep.name == name}
    if not found:
        known = sorted({*kind.built_in, *(ep.name for ep in points)})
        raise LawError(
            f"no {kind.word} named {name!r}: not built in, not module:Class, and no entry point of group "
            f"{kind.group!r} has that name" + _close(name, known)
        )
    if len(found) > 1:
        raise LawError(f"entry point {name!r} of group {kind.group!r} names several classes: {sorted(found)}")
    return _imported(found.pop(), name, kind)


def declared_params(cls: type, law: str = "", kind: Kind = FOLLOWER) -> dict[str, bool | int | float | str]:
    """The parameters ``cls`` declares (``PARAMS``: name -> default), checked."""
    raw = getattr(cls, "PARAMS", None)
    if raw is None:
        return {}
    who = f"{cls.__qualname__}.PARAMS" + (f" ({kind.word} {law!r})" if law else "")
    if not isinstance(raw, Mapping):
        raise LawError(f"{who} must be a mapping of name -> default, got {type(raw).__name__}")
    out: dict[str, bool | int | float | str] = {}
    for name, default in raw.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise LawError(f"{who}: parameter names must be identifiers, got {name!r}")
        if not isinstance(default, (bool, int, float, str)) or not _finite(default):
            raise LawError(f"{who}[{name!r}]: a default must be a finite number, a boolean or a string: {default!r}")
        out[name] = default
    return out


def _finite(value: bool | int | float | str) -> bool:
    return not isinstance(value, float) or math.isfinite(value)


def _close(name: str, known: list[str]) -> str:
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else ""


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:200]}" if text else type(exc).__name__
