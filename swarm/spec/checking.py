"""How a scenario's tables are checked and their errors worded: every value
of the file before any table is read (numbers, text, depth), a table against
its keys (types, ranges, defaults, unknown keys with a suggestion), times
against the ticks a run can count, names the run writes, a validating
constructor's error given its key, robot ids as ranges.
"""

from __future__ import annotations

import difflib
import math
import unicodedata
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from formation_swarm.common.checks import MAX_TICKS, tick_limit
from formation_swarm.spec.keys import MAX_DEPTH, Key, ScenarioError, type_name

# TOML's integers, and msgpack's: 64 bits.
INT_MIN, INT_MAX = -(2**63), 2**63 - 1


def suggest(key: str, valid: Sequence[str]) -> str:
    """The end of an "unknown key" error: the closest valid key, or all of them."""
    close = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else f"; valid keys: {', '.join(valid)}"


def check_values(raw: Any) -> None:
    """Every value of a scenario's tree, before any table is read: numbers
    finite (TOML has nan and inf) and integers of 64 bits (TOML's reader takes
    any), text that UTF-8 writes (the scenario as run is written back for every
    process), tables and arrays at most MAX_DEPTH deep. Walked without
    recursion, in file order; ScenarioError names the first key at fault."""
    stack: list[tuple[str, Any, int]] = [("", raw, 1)]
    while stack:
        where, value, depth = stack.pop()
        if isinstance(value, (Mapping, list)):
            if depth > MAX_DEPTH:
                raise ScenarioError(
                    f"{where or 'the scenario'}: tables and arrays nested more than {MAX_DEPTH} deep"
                    f" (a scenario needs 6)",
                    key=where or None,
                )
            if isinstance(value, Mapping):
                children = []
                for k, v in value.items():
                    path = f"{where}.{k}" if where else str(k)
                    _check_text(f"{path} (the key)", str(k), path)
                    children.append((path, v, depth + 1))
            else:
                children = [(f"{where}[{i}]", v, depth + 1) for i, v in enumerate(value)]
            stack.extend(reversed(children))
        elif isinstance(value, bool):
            continue
        elif isinstance(value, float) and not math.isfinite(value):
            # TOML reads a bare nan or inf as a number: for a string it must be quoted.
            raise ScenarioError(
                f'{where} must be a finite number, got {value!r} (as a string, quote it: "{value!r}")',
                key=where,
                value=value,
            )
        elif isinstance(value, int) and not INT_MIN <= value <= INT_MAX:
            raise ScenarioError(
                f"{where} must be an integer in [-2**63, 2**63 - 1] (64 bits), got one of {value.bit_length()} bits",
                key=where,
                value=value,
            )
        elif isinstance(value, str):
            _check_text(where, value, where)


def _check_text(where: str, text: str, key: str) -> None:
    """Text UTF-8 can write: a lone surrogate (what a command line's undecodable bytes become) cannot be."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise ScenarioError(f"{where} must be text that UTF-8 can write, got {text!r}", key=key, value=text) from None


def check_name(where: str, name: str, key: str | None = None) -> None:
    """A name the run prints in its lines and logs: one line, without control
    characters; ``key``: the key the name is (``where`` if None)."""
    bad = next((ch for ch in name if unicodedata.category(ch) in ("Cc", "Zl", "Zp")), None)
    if bad is not None:
        raise ScenarioError(
            f"{where} must be one line of printable text, got {name!r} (it holds {bad!r})",
            key=where if key is None else key,
            value=name,
        )


def check_times(where: str, table: Mapping[str, Any], schema: Mapping[str, Key], dt_s: float) -> None:
    """Every time of a checked table (a key in s, but the tick itself) at most
    MAX_TICKS ticks of ``dt_s``: the run's length travels in its messages as a
    tick count, and the agents count the others in ticks too."""
    for key, spec in schema.items():
        value = table.get(key)
        if spec.unit != "s" or key == "dt_s" or isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        if value / dt_s > MAX_TICKS:
            raise ScenarioError(
                f"{where}.{key} must be at most {tick_limit(dt_s)}, got {value!r}", key=f"{where}.{key}", value=value
            )


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
        raise ScenarioError(f"{where} must be {type_name(spec.types)}, got {got}", key=where, value=value)
    if isinstance(value, float) and not math.isfinite(value):
        raise ScenarioError(f"{where} must be a finite number, got {value!r}", key=where, value=value)
    if (why := spec.check_range(where, value)) is not None:
        raise ScenarioError(why, key=where, value=value)
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
