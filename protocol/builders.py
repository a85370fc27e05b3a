"""Functions made once per message class, from its fields, for the decoder
(protocol.codec): one that builds a message from its values in wire order,
and one that decodes the common case (every value already what its check
would return) in a single expression. Both are written out as Python source
from the dataclass's own field names, as dataclasses writes ``__init__``.

They change no outcome: the fast decoder answers only when every check
would pass and return the value as it is, and gives None otherwise, for the
checks one by one to decide (and name the reason).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

# Names the written functions use themselves: no field may take one.
_OWN = frozenset(("raw", "build", "isfinite", "cls", "new", "self"))


def _identifiers(names: Sequence[str], owner: str) -> None:
    # Field names of our own classes: never false.
    if not all(n.isidentifier() and n not in _OWN and not n.startswith(("_", "check_", "set_")) for n in names):
        raise TypeError(f"{owner}: a field name is not an identifier the decoder may use")


def builder(cls: type, names: Sequence[str]) -> Callable[..., Any]:
    """A function of the fields' values in wire order that returns the message.

    A frozen dataclass with slots (every message of ours) is made without its
    ``__init__``: the object, then each slot set through its descriptor (a
    third of the time). Any other class (a ``__post_init__`` to run, fields
    without slots) is built by keyword, ``cls(name=value, ...)``."""
    _identifiers(names, cls.__name__)
    slotted = all(type(getattr(cls, n, None)).__name__ == "member_descriptor" for n in names)
    space: dict[str, Any] = {"cls": cls, "new": object.__new__}
    args = ", ".join(names)
    if slotted and not hasattr(cls, "__post_init__"):
        space.update({f"set_{n}": getattr(cls, n).__set__ for n in names})
        body = "    self = new(cls)\n" + "".join(f"    set_{n}(self, {n})\n" for n in names) + "    return self\n"
    else:
        body = "    return cls(" + ", ".join(f"{n}={n}" for n in names) + ")\n"
    exec(f"def build({args}):\n{body}", space)
    return space["build"]  # type: ignore[no-any-return]


def fast_decoder(
    names: Sequence[str],
    header: Sequence[tuple[int, int]],
    checks: Sequence[Callable[[str, Any], Any]],
    build: Callable[..., Any],
    owner: str,
) -> Callable[[list[Any]], Any]:
    """A function of a decoded msgpack list ``[tag, version, *values]`` (of
    the right length, its tag and version checked) that returns the message
    when every value passes as it is, else None. ``header``: the bounds of
    the three header ints (sender, seq, tick); ``checks``: the other fields'.
    A check with a ``fast`` attribute (a test of ``{v}`` that holds exactly
    when it returns ``v`` unchanged, or ``fast_value`` of ``{v}`` when it has
    one) is written out; any other is called."""
    _identifiers(names, owner)
    space: dict[str, Any] = {"build": build, "isfinite": math.isfinite}
    tests, args = [], []
    for name, (lo, hi) in zip(names[:3], header, strict=True):
        if type(lo) is not int or type(hi) is not int:
            raise TypeError(f"{owner}: header bounds must be ints")
        tests.append(f"type({name}) is int and {lo} <= {name} <= {hi}")
        args.append(name)
    for k, (name, check) in enumerate(zip(names[3:], checks, strict=True)):
        fast = getattr(check, "fast", None)
        if fast is not None:
            tests.append("(" + fast.format(v=name) + ")")
            args.append(getattr(check, "fast_value", "{v}").format(v=name))
        else:
            space[f"check_{k}"] = check
            args.append(f"check_{k}({name!r}, {name})")
    src = (
        "def decode(raw):\n"
        f"    _tag, _version, {', '.join(names)} = raw\n"
        f"    if {' and '.join(tests)}:\n"
        f"        return build({', '.join(args)})\n"
        "    return None\n"
    )
    exec(src, space)
    return space["decode"]  # type: ignore[no-any-return]
