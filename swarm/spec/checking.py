"""How a scenario's tables are checked and their errors worded: a table
against its keys (types, ranges, defaults, unknown keys with a suggestion),
a validating constructor's error given its key, robot ids as ranges.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from formation_swarm.spec.keys import Key, ScenarioError, type_name


def suggest(key: str, valid: Sequence[str]) -> str:
    """The end of an "unknown key" error: the closest valid key, or all of them."""
    close = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else f"; valid keys: {', '.join(valid)}"


def check_table(raw: Any, where: str, schema: Mapping[str, Key]) -> dict[str, Any]:
    """Check one table against its schema (types and ranges); fill defaults; reject unknown keys."""
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise ScenarioError(f"{where} must be a table, got {type(raw).__name__}")
    out: dict[str, Any] = {}
    for key, value in raw.items():
        if key not in schema:
            raise ScenarioError(f"unknown key {where}.{key}" + suggest(key, tuple(schema)))
        out[key] = _checked(f"{where}.{key}", schema[key], value)
    for key, spec in schema.items():
        if key not in out:
            if spec.required:
                raise ScenarioError(f"missing key {where}.{key}")
            out[key] = spec.default
    return out


def _checked(where: str, spec: Key, value: Any) -> Any:
    """One key's value, if it has the key's type and lies in its range."""
    types = spec.types if isinstance(spec.types, tuple) else (spec.types,)
    if (isinstance(value, bool) and bool not in types) or not isinstance(value, types):
        got = str(value).lower() if isinstance(value, bool) else repr(value)  # as TOML writes it
        raise ScenarioError(f"{where} must be {type_name(spec.types)}, got {got}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ScenarioError(f"{where} must be finite, got {value!r}")
    if (why := spec.check_range(where, value)) is not None:
        raise ScenarioError(why)
    return value


def wrapped(where: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """Call a constructor that validates, re-raising its error with the scenario key."""
    try:
        return fn(*args, **kwargs)
    except (ValueError, TypeError) as exc:
        raise ScenarioError(f"{where}: {exc}") from None


def id_ranges(ids: Sequence[int]) -> str:
    """[2, 3, 4, 7] -> "2-4, 7"."""
    runs: list[list[int]] = []
    for i in sorted(ids):
        if runs and i == runs[-1][-1] + 1:
            runs[-1].append(i)
        else:
            runs.append([i])
    return ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)


def is_point(value: Any) -> bool:
    """Whether a TOML value is a point [x_m, y_m]: two numbers, neither a boolean."""
    return (
        isinstance(value, list)
        and len(value) == 2
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    )
