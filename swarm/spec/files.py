"""Scenario files as text: the shipped scenarios found by name, values given
on the command line (``--set KEY=VALUE``), and the scenario as run written
back to TOML. Loading and checking are in ``formation_swarm.spec.scenario``."""

from __future__ import annotations

import difflib
import importlib.resources
import re
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from formation_swarm.spec.keys import MAX_DEPTH, ScenarioError


def shipped() -> dict[str, Path]:
    """The scenarios installed with the package, by name (file name without .toml)."""
    folder = Path(str(importlib.resources.files("formation_swarm.scenarios")))
    return {p.stem: p for p in sorted(folder.glob("*.toml"))}


def description(path: Path) -> str:
    """A scenario file's one-line description: its first comment line."""
    for text in path.read_text().splitlines():
        if text.startswith("#"):
            return text.lstrip("# ").strip()
        if text.strip():
            break
    return ""


def resolve(spec: str | Path) -> Path:
    """A scenario's file from a path or from the name of a shipped scenario."""
    if not isinstance(spec, (str, Path)):
        raise ScenarioError(
            f"a scenario is a shipped scenario's name or a TOML file's path, got {type(spec).__name__} {spec!r:.60}"
        )
    p = Path(spec)
    if p.suffix == ".toml" or p.parent != Path(".") or p.exists():
        if not p.is_file():
            where = "" if p.is_absolute() else f" (relative to the working folder, {Path.cwd()})"
            raise ScenarioError(f"scenario file not found: {p}{where}")
        return p
    known = shipped()
    if str(spec) in known:
        return known[str(spec)]
    close = difflib.get_close_matches(str(spec), list(known), n=1, cutoff=0.5)
    hint = f"; did you mean {close[0]!r}?" if close else f"; shipped scenarios: {', '.join(known)}"
    raise ScenarioError(f"no scenario file or shipped scenario named {str(spec)!r}" + hint)


def parse_value(text: str) -> Any:
    """A value given on the command line: TOML (numbers, booleans, quoted
    strings, arrays), or else the text itself as a string. ScenarioError for
    TOML no scenario holds: nested too deep, an integer of thousands of digits."""
    try:
        return tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        return text.strip()
    except RecursionError:  # tomllib recurses once per level of arrays and inline tables
        raise ScenarioError(
            f"the value {_short(text)}: arrays or inline tables nested more than {MAX_DEPTH} deep"
        ) from None
    except ValueError as exc:  # Python reads no integer of more than 4300 digits
        raise ScenarioError(f"the value {_short(text)}: {exc}") from None


def _short(text: str) -> str:
    """A value as an error quotes it: its start, if it is long."""
    text = text.strip()
    return repr(text) if len(text) <= 40 else f"{text[:30]!r}... ({len(text)} characters)"


def parse_override(text: str) -> tuple[str, Any]:
    """``"leader.speed_mps=1.6"`` -> ("leader.speed_mps", 1.6)."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip() or not value.strip():
        raise ScenarioError(f"--set takes KEY=VALUE (e.g. leader.speed_mps=1.6), got {text!r}")
    if key.count(".") >= MAX_DEPTH:  # each part a table inside the one before
        raise ScenarioError(
            f"--set {_short(key)}: a key of at most {MAX_DEPTH} parts, got {key.count('.') + 1}", key=key.strip()
        )
    try:
        return key.strip(), parse_value(value)
    except ScenarioError as exc:
        raise ScenarioError(f"--set {key.strip()}: {exc}", key=key.strip()) from None


def parse_overrides(texts: Sequence[str]) -> dict[str, Any]:
    """Each ``--set KEY=VALUE`` parsed; ScenarioError for a key given twice
    (which one would count is not for us to guess)."""
    out: dict[str, Any] = {}
    for text in texts:
        key, value = parse_override(text)
        if key in out:
            raise ScenarioError(f"--set {key} is given twice ({out[key]!r} and {value!r}): give it once")
        out[key] = value
    return out


def deep_set(raw: Mapping[str, Any], path: tuple[str, ...], value: Any) -> dict[str, Any]:
    out = dict(raw)
    if len(path) == 1:
        out[path[0]] = value
        return out
    inner = out.get(path[0], {})
    if not isinstance(inner, Mapping):
        raise ScenarioError(f"cannot set {'.'.join(path)}: {path[0]} is not a table")
    out[path[0]] = deep_set(inner, path[1:], value)
    return out


def dumps(raw: Mapping[str, Any]) -> str:
    """The scenario as run, as TOML (the subset scenarios use): every process
    reads it back, so any text, names and keys included, is written so that
    tomllib reads back what was written."""
    lines: list[str] = []
    _write_table(lines, "", raw)
    return "\n".join(lines)


# A basic string's escapes: the quote, the backslash and every control character.
_ESCAPES = {i: f"\\u{i:04X}" for i in (*range(0x20), 0x7F)} | {
    ord('"'): '\\"',
    ord("\\"): "\\\\",
    ord("\b"): "\\b",
    ord("\t"): "\\t",
    ord("\n"): "\\n",
    ord("\f"): "\\f",
    ord("\r"): "\\r",
}
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")  # TOML's bare keys: ASCII only


def _toml_string(text: str) -> str:
    return '"' + text.translate(_ESCAPES) + '"'


def _toml_key(key: Any, identifiers_only: bool = False) -> str:
    """A key as TOML writes it: bare where TOML allows (``identifiers_only``:
    where it is an ASCII identifier, as a table's values have always been
    written), else quoted."""
    k = str(key)
    bare = k.isascii() and k.isidentifier() if identifiers_only else _BARE_KEY.fullmatch(k) is not None
    return k if bare else _toml_string(k)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return _toml_string(v)
    if isinstance(v, int):
        return str(int(v))
    if isinstance(v, float):
        return repr(float(v))  # a numpy float's repr is not TOML
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_string(str(k))} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _write_table(lines: list[str], prefix: str, t: Mapping[str, Any]) -> None:
    """One table's lines: its values, then its sub-tables, then its arrays of tables."""
    scalars = {k: v for k, v in t.items() if not isinstance(v, dict) and not _is_table_array(v)}
    subs = {k: v for k, v in t.items() if isinstance(v, dict)}
    arrays = {k: v for k, v in t.items() if _is_table_array(v)}
    if prefix and (scalars or not subs):
        lines.append(f"[{prefix}]")
    for k, v in scalars.items():
        lines.append(f"{_toml_key(k, identifiers_only=True)} = {_toml_value(v)}")
    if scalars:
        lines.append("")
    for k, v in subs.items():
        _write_table(lines, f"{prefix}.{_toml_key(k)}" if prefix else _toml_key(k), v)
    for k, v in arrays.items():
        for item in v:
            lines.append(f"[[{prefix + '.' if prefix else ''}{_toml_key(k)}]]")
            lines += [f"{_toml_key(ik, identifiers_only=True)} = {_toml_value(iv)}" for ik, iv in item.items()]
            lines.append("")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)
