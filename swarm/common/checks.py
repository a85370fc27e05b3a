"""Validation helpers shared by the pure maths: each raises ValueError or
TypeError naming the parameter and the offending value."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

# A run's seed keys numpy's SeedSequence (non-negative integers only) and the
# link layer's drop hash (packed as a signed 64-bit integer): both take this range.
SEED_MAX = 2**63 - 1
# The most ticks a run may count: a message's tick and a Status's total_ticks
# are refused past protocol.codec.MAX_TICK, this number (common sits below
# protocol, so it is repeated here; tests/unit/common/test_limits.py keeps the two equal).
# A scenario's times (its duration, a fault's start and length) stay within it.
MAX_TICKS = 2**53


def tick_limit(dt_s: float) -> str:
    """MAX_TICKS as an error says it: in ticks of the run's step and in seconds."""
    return (
        f"2**53 ticks of run.dt_s = {dt_s:g} s (about {MAX_TICKS * dt_s:.4g} s, the most a message's tick count "
        "carries)"
    )


def finite(name: str, value: object) -> float:
    """Return ``value`` as a float, rejecting non-numbers, NaN and inf."""
    if type(value) is float and math.isfinite(value):
        return value  # the common case, on every controller tick: checked first
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__} {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise ValueError(f"{name} must be finite, got {out!r}")
    return out


def positive(name: str, value: object) -> float:
    out = finite(name, value)
    if out <= 0.0:
        raise ValueError(f"{name} must be > 0, got {out!r}")
    return out


def non_negative(name: str, value: object) -> float:
    out = finite(name, value)
    if out < 0.0:
        raise ValueError(f"{name} must be >= 0, got {out!r}")
    return out


def probability(name: str, value: object) -> float:
    out = finite(name, value)
    if not 0.0 <= out <= 1.0:
        raise ValueError(f"{name} must be in [0, 1], got {out!r}")
    return out


def vector(name: str, value: object, size: int) -> tuple[float, ...]:
    """Return a finite vector of exactly ``size`` numbers as a tuple."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise TypeError(f"{name} must be a sequence of {size} numbers, got {value!r}")
    arr = np.asarray(value, dtype=object).ravel() if isinstance(value, np.ndarray) else value
    if len(arr) != size:
        raise ValueError(f"{name} must have {size} elements, got {len(arr)}: {value!r}")
    return tuple(finite(f"{name}[{i}]", v) for i, v in enumerate(arr))
