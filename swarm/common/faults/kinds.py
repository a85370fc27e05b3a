"""The kinds of fault a schedule may name: each kind's group (process, link,
network, sensor, actuator), its parameters with their units and ranges, and
how a time or a number is read from the grammar's text (docs/faults.md).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

PROCESS = "process"
LINK = "link"
NETWORK = "network"
SENSOR = "sensor"
ACTUATOR = "actuator"

LINK_CLASSES = ("obs", "cmd", "formation")
ALL_LINKS = "links"


@dataclass(frozen=True)
class Param:
    """One parameter of a fault kind: a number in [low, high] or one of ``choices``."""

    doc: str
    unit: str = ""
    default: float | str | None = None  # None: required (unless ``one_of`` says otherwise)
    low: float = 0.0
    high: float = math.inf
    open_low: bool = False
    choices: tuple[str, ...] = ()

    def check(self, where: str, value: Any) -> float | str:
        if self.choices:
            if value not in self.choices:
                raise ValueError(f"{where} must be one of {', '.join(self.choices)}, got {value!r}")
            return str(value)
        if isinstance(value, str):  # a duration as the fault's times are written: 1, 1s or 500ms
            value = seconds(where, value) if self.unit == "s" else _number(where, value, self.unit)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not _finite(value):
            raise ValueError(f"{where} must be a finite number, got {value!r}")
        low_ok = value > self.low if self.open_low else value >= self.low
        if not low_ok or value > self.high:
            lo = "(" if self.open_low else "["
            raise ValueError(f"{where} must be in {lo}{self.low:g}, {self.high:g}], got {value!r}")
        return float(value)


def _p(doc: str, default: float | None = None) -> Param:
    return Param(doc, "", default, 0.0, 1.0)


@dataclass(frozen=True)
class Kind:
    group: str
    doc: str
    params: Mapping[str, Param] = field(default_factory=dict)
    needs_for: bool = False  # a duration is required
    allows_for: bool = True
    one_of: tuple[str, ...] = ()  # exactly one of these parameters is given


KINDS: dict[str, Kind] = {
    "kill": Kind(PROCESS, "SIGKILL the process; an agent's robot stops where it is", allows_for=False),
    "restart": Kind(
        PROCESS,
        "SIGKILL an agent, then start a fresh process for the same robot `after` seconds later; "
        "the world re-admits the robot when it is back",
        {"after": Param("time between the kill and the fresh start", "s", 1.0)},
        allows_for=False,
    ),
    "freeze": Kind(PROCESS, "SIGSTOP the process, SIGCONT it `for` seconds later", needs_for=True),
    "drop": Kind(LINK, "each message is lost with probability p", {"p": _p("probability of loss")}),
    "burst": Kind(
        LINK,
        "Gilbert-Elliott losses: a two-state chain per link, stepped at each message",
        {
            "p_bad": _p("probability, per message, of going from the good state to the bad one"),
            "p_good": _p("probability, per message, of going back from bad to good"),
            "loss": _p("probability of loss in the bad state (none in the good one)", 1.0),
        },
    ),
    "delay": Kind(
        LINK,
        "each message is held back: `ticks` (lockstep) or `ms` (real time; either unit is converted "
        "with dt in the other mode), plus a uniform jitter of up to `jitter_ticks`/`jitter_ms`",
        {
            "ticks": Param("fixed delay", "ticks", None),
            "ms": Param("fixed delay", "ms", None),
            "jitter_ticks": Param("largest extra delay, drawn uniformly per message", "ticks", 0.0),
            "jitter_ms": Param("largest extra delay, drawn uniformly per message", "ms", 0.0),
        },
        one_of=("ticks", "ms"),
    ),
    "duplicate": Kind(LINK, "each message is delivered twice with probability p", {"p": _p("probability")}),
    "reorder": Kind(
        LINK,
        "each message is held back with probability p and delivered after the link's next message",
        {"p": _p("probability")},
    ),
    "partition": Kind(
        NETWORK,
        "cut the robots off, both ways: from the world (observations and commands), from their leader "
        "(formation codes) or both",
        {"from": Param("what they are cut off from", default="both", choices=("world", "leader", "both"))},
        needs_for=True,
    ),
    "blackout": Kind(SENSOR, "the camera sees nothing (camera faults apply to followers: the leader has none)"),
    "bias": Kind(
        SENSOR,
        "every camera reading is offset",
        {
            "rho_m": Param("added to the distance", "m", 0.0, -math.inf),
            "phi_deg": Param("added to the orientation", "deg", 0.0, -math.inf),
            "beta_deg": Param("added to the bearing", "deg", 0.0, -math.inf),
        },
    ),
    "outliers": Kind(
        SENSOR,
        "each reading is replaced, with probability p, by a wrong one drawn uniformly within the camera's "
        "range and field of view",
        {"p": _p("probability")},
    ),
    "range": Kind(
        SENSOR, "the camera sees no farther than `m`", {"m": Param("the reduced range", "m", None, open_low=True)}
    ),
    "wheel_noise": Kind(
        ACTUATOR,
        "each wheel's speed gets Gaussian noise, drawn per tick",
        {"sigma_mps": Param("standard deviation", "m/s", None)},
    ),
    "wheel_bias": Kind(
        ACTUATOR,
        "each wheel turns a fraction faster (> 0) or slower (< 0) than commanded",
        {
            "left": Param("fraction added to the left wheel's speed", "", 0.0, -1.0, 1.0),
            "right": Param("fraction added to the right wheel's speed", "", 0.0, -1.0, 1.0),
        },
    ),
    "slip": Kind(
        ACTUATOR,
        "the wheels lose a fraction of their speed on the ground",
        {
            "fraction": Param("fraction of the speed lost", "", None, 0.0, 1.0),
            "wheel": Param("which wheel slips", default="both", choices=("left", "right", "both")),
        },
    ),
    "stuck": Kind(
        ACTUATOR,
        "a wheel does not turn",
        {"wheel": Param("which wheel", default="left", choices=("left", "right", "both"))},
    ),
}

_TIME = re.compile(r"^([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)(ms|s)?$")


def _number(where: str, text: str, unit: str = "") -> float:
    given, text = text, text.strip()
    if unit in ("s", "ms", "m", "m/s", "deg") and text.endswith(unit):
        text = text[: -len(unit)]
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{where} must be a number{f' in {unit}' if unit else ''}, got {given!r}") from None


def seconds(where: str, value: Any) -> float:
    """``20``, ``20s``, ``"1500ms"`` -> seconds (>= 0, finite)."""
    if isinstance(value, str):
        m = _TIME.match(value.strip())
        if not m:
            sign = "a time >= 0 s, " if value.strip().startswith("-") else "a time "
            raise ValueError(f"{where} must be {sign}such as 20, 20s or 1500ms, got {value!r}")
        out = float(m.group(1)) / (1000.0 if m.group(2) == "ms" else 1.0)
    elif isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where} must be a time in s, got {value!r}")
    else:
        out = float(value) if _finite(value) else math.inf
    if not (math.isfinite(out) and out >= 0.0):
        raise ValueError(f"{where} must be a time >= 0 s, got {value!r}")
    return out


def _finite(value: float) -> bool:
    """Whether a number is a finite float (an integer too large for a float is not)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def value_text(v: float | str) -> str:
    """A parameter's value as the grammar writes it."""
    return v if isinstance(v, str) else f"{v:g}"
