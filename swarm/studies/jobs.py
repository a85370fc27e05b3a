"""A sweep's runs: each a combination of scenario values (``--set``) and a
seed, named so that a finished run is found again, and only for the very
same scenario.
"""

from __future__ import annotations

import hashlib
import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Job:
    label: str  # the combination, e.g. "controller.vn=1.5"
    overrides: Mapping[str, Any]
    seed: int
    # What else makes the run (the scenario as run, faults included, without its
    # seed): a finished run is reused only for the very same scenario.
    context: str = ""

    @property
    def name(self) -> str:
        digest = hashlib.blake2b((self.label + "\n" + self.context).encode(), digest_size=4).hexdigest()
        return f"{slug(self.label) or 'base'}-{digest}-s{self.seed}"


def settings_text(settings: Mapping[str, Any]) -> str:
    """A job's settings as its label says them: ``key=value, key=value``."""
    return ", ".join(f"{k}={v}" for k, v in settings.items())


def parse_set(text: str) -> tuple[str, list[Any]]:
    """``key=v1,v2`` -> (key, [v1, v2]); values are TOML (numbers, booleans,
    quoted strings) or else bare strings."""
    key, sep, values = text.partition("=")
    if not sep or not key.strip() or not values.strip():
        raise ValueError(f"--set takes key=v1,v2,..., got {text!r}")
    from formation_swarm.spec.files import parse_value

    key = key.strip()
    if key == "run.seed":
        raise ValueError("--set run.seed: a sweep gives every combination its seeds; use --seeds N and --seed-start S")
    out = [parse_value(raw) for raw in values.split(",")]
    for i, v in enumerate(out):
        # Equal values (1.5 and 1.50, 2 and 2.0) would make one run twice, in one folder at once.
        if any(v == w and type(v) is type(w) or _numbers_equal(v, w) for w in out[:i]):
            first = next(w for w in values.split(",")[:i] if parse_value(w) == v)
            raise ValueError(
                f"--set {key}: the value {values.split(',')[i].strip()!r} is given twice "
                f"(as {first.strip()!r} before it: the same value)"
            )
    return key, out


def _numbers_equal(a: Any, b: Any) -> bool:
    numbers = (int, float)
    return (
        isinstance(a, numbers)
        and isinstance(b, numbers)
        and not isinstance(a, bool)
        and not isinstance(b, bool)
        and a == b
    )


def grid(sets: Sequence[tuple[str, list[Any]]]) -> list[tuple[str, dict[str, Any]]]:
    """Every combination of the values, as (label, overrides)."""
    if not sets:
        return [("", {})]
    keys = [k for k, _ in sets]
    combos = itertools.product(*(v for _, v in sets))
    return [
        (" ".join(f"{k}={v}" for k, v in zip(keys, c, strict=True)), dict(zip(keys, c, strict=True))) for c in combos
    ]


def slug(text: str) -> str:
    """``text`` as a file name's part: letters, digits, ``-_.``; at most 60 characters."""
    out = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in text)
    return out.strip("_")[:60]
