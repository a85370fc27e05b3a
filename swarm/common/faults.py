"""The fault schedule of a run: one small grammar for scenario files, the
command line and the pytest fixtures (docs/faults.md explains each fault).

A fault as a string::

    KIND TARGET@START [for=DURATION] [PARAM=VALUE ...]

    kill agent-3@20s                      restart agent-2@20s after=1s
    freeze agent-2@15s for=3s             drop obs:2@10s for=5s p=0.3
    burst cmd:2,3@10s p_bad=0.05 p_good=0.3
    delay formation@5s for=10s ticks=4 jitter_ticks=2
    partition 2,3@12s for=15s from=world  blackout 3@20s for=2s
    wheel_noise *@0s sigma_mps=0.1        stuck 2@30s for=4s wheel=left

and the same as a TOML table (``[[faults]]``: ``kind``, ``target``,
``at_s``, ``for_s`` and the parameters by name) or as a :class:`Fault`.
Times are seconds of the run (``20``, ``20s`` or ``1500ms``); a fault starts
at tick ``round(at_s / dt)`` and lasts ``round(for_s / dt)`` ticks, for good
when ``for`` is left out (where the kind allows it).

Targets: ``agent-N`` or ``logger`` for process faults; ``CLASS[:ROBOTS]``
for link faults, CLASS one of ``obs`` (world -> robot), ``cmd`` (robot ->
world), ``formation`` (leader -> follower) or ``links`` (all three), ROBOTS
a comma list of ids or ``*`` (the default); ROBOTS alone for partitions,
sensor and actuator faults.

Nothing here knows Zenoh or processes: the world, the agents and the
launcher each take the part of the schedule that is theirs.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

PROCESS = "process"
LINK = "link"
NETWORK = "network"
SENSOR = "sensor"
ACTUATOR = "actuator"

LINK_CLASSES = ("obs", "cmd", "formation")
ALL_LINKS = "links"
MAX_FAULTS = 256


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
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
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
        out = float(value)
    if not (math.isfinite(out) and out >= 0.0):
        raise ValueError(f"{where} must be a time >= 0 s, got {value!r}")
    return out


def _robots(where: str, text: str) -> tuple[int, ...] | None:
    """``"2,3"`` -> (2, 3); ``"*"`` -> None (every robot the fault can apply to)."""
    text = text.strip()
    if text in ("*", ""):
        return None
    out = []
    for part in text.split(","):
        if not part.strip().isdigit():
            raise ValueError(f"{where}: robots are ids separated by commas or *, got {text!r}")
        out.append(int(part))
    if len(set(out)) != len(out):
        raise ValueError(f"{where}: a robot is named twice in {text!r}")
    return tuple(sorted(out))


def _robots_text(robots: tuple[int, ...] | None) -> str:
    return "*" if robots is None else ",".join(map(str, robots))


def _fmt(v: float | str) -> str:
    return v if isinstance(v, str) else f"{v:g}"


@dataclass(frozen=True)
class Fault:
    """One scheduled fault. Build it with :meth:`make`, :meth:`parse` or
    :meth:`from_table`; all three check it the same way."""

    kind: str
    target: str
    at_s: float
    for_s: float | None = None
    params: tuple[tuple[str, float | str], ...] = ()

    # -- construction -----------------------------------------------------------
    @classmethod
    def make(cls, kind: str, target: str, at_s: Any, for_s: Any = None, **params: Any) -> Fault:
        if kind not in KINDS:
            close = difflib.get_close_matches(str(kind), list(KINDS), n=1, cutoff=0.6)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise ValueError(f"unknown fault kind {kind!r}; {hint}kinds: {', '.join(KINDS)}")
        spec = KINDS[kind]
        where = f"fault {kind!r}"
        target = _canonical_target(kind, str(target), where)
        at = seconds(f"{where}: the start", at_s)
        checked: dict[str, float | str] = {}
        for name, value in params.items():
            if name not in spec.params:
                known = ", ".join(spec.params) or "none"
                close = difflib.get_close_matches(name, [*spec.params, "for", "for_s"], n=1, cutoff=0.5)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise ValueError(f"{where} has no parameter {name!r}{hint} (its parameters: {known})")
            checked[name] = spec.params[name].check(f"{where}: {name}", value)
        dur = None
        if for_s is not None:
            if not spec.allows_for:
                raise ValueError(f"{where} takes no duration (for=)")
            dur = seconds(f"{where}: for", for_s)
            if dur <= 0:
                raise ValueError(f"{where}: for must be > 0 s, got {for_s!r}")
        elif spec.needs_for:
            raise ValueError(f"{where} needs a duration: for=SECONDS")
        if spec.one_of:
            given = [n for n in spec.one_of if n in checked]
            if len(given) != 1:
                raise ValueError(f"{where} needs exactly one of {' or '.join(spec.one_of)}")
        for name, p in spec.params.items():
            if name not in checked and p.default is None and name not in spec.one_of:
                raise ValueError(f"{where} needs {name}=VALUE ({p.doc})")
        return cls(kind, target, at, dur, tuple(sorted(checked.items())))

    @classmethod
    def parse(cls, text: str) -> Fault:
        """``"kill agent-3@20s"``, ``"drop obs:2@10s for=5s p=0.3"``."""
        if not isinstance(text, str):
            raise ValueError(f"a fault is a string such as 'kill agent-3@20s', got {text!r}")
        words = text.split()
        usage = f"a fault is KIND TARGET@START [for=SECONDS] [PARAM=VALUE ...] (e.g. kill agent-3@20s), got {text!r}"
        if len(words) < 2 or "@" not in words[1]:
            if len(words) == 1 and "@" in words[0] and words[0].split("@")[0].startswith("agent-"):
                raise ValueError(f"{usage}; did you mean 'kill {words[0]}'?")
            raise ValueError(usage)
        kind = words[0]
        target, _, start = words[1].rpartition("@")
        kwargs: dict[str, Any] = {}
        for word in words[2:]:
            name, sep, value = word.partition("=")
            if not sep or not name or not value:
                raise ValueError(f"{usage}: {word!r} is not PARAM=VALUE")
            if name in kwargs:
                raise ValueError(f"{usage}: {name} is given twice")
            kwargs[name] = value
        for_s = kwargs.pop("for", None)
        return cls.make(kind, target, start, for_s, **kwargs)

    @classmethod
    def from_table(cls, table: Mapping[str, Any], where: str = "faults") -> Fault:
        """A ``[[faults]]`` table: kind, target, at_s, for_s and parameters by name."""
        if isinstance(table, str):
            return cls.parse(table)
        if not isinstance(table, Mapping):
            raise ValueError(f"{where} must be a table or a string, got {table!r}")
        t = dict(table)
        missing = [k for k in ("kind", "target", "at_s") if k not in t]
        if missing:
            raise ValueError(f"{where} needs {', '.join(missing)} (e.g. kind = 'kill', target = 'agent-3', at_s = 20)")
        kind, target, at_s = t.pop("kind"), t.pop("target"), t.pop("at_s")
        for_s = t.pop("for_s", None)
        if not isinstance(kind, str) or not isinstance(target, (str, int)) or isinstance(target, bool):
            raise ValueError(f"{where}: kind and target must be strings, got {kind!r}, {target!r}")
        return cls.make(kind, str(target), at_s, for_s, **t)

    @classmethod
    def coerce(cls, value: Fault | str | Mapping[str, Any]) -> Fault:
        if isinstance(value, Fault):
            return value
        return cls.from_table(value) if isinstance(value, Mapping) else cls.parse(value)

    # -- reading ----------------------------------------------------------------
    @property
    def group(self) -> str:
        return KINDS[self.kind].group

    def param(self, name: str) -> Any:
        got = dict(self.params)
        if name in got:
            return got[name]
        return KINDS[self.kind].params[name].default

    def has(self, name: str) -> bool:
        return name in dict(self.params)

    def start_tick(self, dt_s: float) -> int:
        return int(round(self.at_s / dt_s))

    def end_tick(self, dt_s: float) -> int | None:
        """The first tick the fault no longer applies to (None: to the run's end).
        A restart's end is the tick of the fresh start."""
        if self.kind == "restart":
            return self.start_tick(dt_s) + max(1, int(round(self.param("after") / dt_s)))
        if self.for_s is None:
            return None
        return self.start_tick(dt_s) + max(1, int(round(self.for_s / dt_s)))

    def active(self, tick: int, dt_s: float) -> bool:
        end = self.end_tick(dt_s)
        return self.start_tick(dt_s) <= tick and (end is None or tick < end)

    @property
    def process(self) -> str | None:
        """``agent-3`` / ``logger`` for process faults."""
        return self.target if self.group == PROCESS else None

    @property
    def robot(self) -> int | None:
        """The robot of a process fault on an agent."""
        if self.group == PROCESS and self.target.startswith("agent-"):
            return int(self.target[len("agent-") :])
        return None

    @property
    def link_classes(self) -> tuple[str, ...]:
        if self.group != LINK:
            return ()
        cls_ = self.target.split(":")[0]
        return LINK_CLASSES if cls_ == ALL_LINKS else (cls_,)

    @property
    def robots(self) -> tuple[int, ...] | None:
        """The robots a link, partition, sensor or actuator fault applies to (None: all)."""
        if self.group == PROCESS:
            return None if self.robot is None else (self.robot,)
        text = self.target.split(":")[1] if self.group == LINK else self.target
        return _robots("", text)

    def applies_to(self, robot_id: int) -> bool:
        robots = self.robots
        return robots is None or robot_id in robots

    def __str__(self) -> str:
        out = [self.kind, f"{self.target}@{self.at_s:g}s"]
        if self.for_s is not None:
            out.append(f"for={self.for_s:g}s")
        out += [f"{k}={_fmt(v)}" for k, v in self.params]
        return " ".join(out)

    def to_table(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": self.kind, "target": self.target, "at_s": self.at_s}
        if self.for_s is not None:
            out["for_s"] = self.for_s
        out.update(dict(self.params))
        return out


def _canonical_target(kind: str, target: str, where: str) -> str:
    group = KINDS[kind].group
    target = target.strip()
    if group == PROCESS:
        if target == "world":
            raise ValueError(
                f"{where}: cannot {kind} the world: it keeps the clock and ends the run; "
                "target an agent (agent-N) or the logger"
            )
        if kind == "restart" and target == "logger":
            raise ValueError(f"{where}: only agents restart (the logger's recording would start over)")
        m = re.fullmatch(r"agent-([0-9]+)", target)
        if not (m or target == "logger"):
            raise ValueError(f"{where}: the target is agent-N or logger, got {target!r}")
        return f"agent-{int(m.group(1))}" if m else target
    if group == LINK:
        cls_, _, robots = target.partition(":")
        if cls_ not in (*LINK_CLASSES, ALL_LINKS):
            raise ValueError(
                f"{where}: the target is a link class ({', '.join((*LINK_CLASSES, ALL_LINKS))}), "
                f"optionally :ROBOTS (e.g. obs:2,3), got {target!r}"
            )
        return f"{cls_}:{_robots_text(_robots(where, robots))}"
    return _robots_text(_robots(where, target))


def check_against(
    faults: Sequence[Fault], robots: Sequence[int], leader_id: int, duration_s: float, dt_s: float
) -> None:
    """Faults that cannot apply to this run: unknown robots, a start past the end,
    a formation link to the leader, a camera fault on the leader (it has none),
    two process faults on one process at once."""
    if len(faults) > MAX_FAULTS:
        raise ValueError(f"at most {MAX_FAULTS} faults, got {len(faults)}")
    known = set(robots)
    busy: dict[str, list[tuple[int, int | None, Fault]]] = {}
    for f in faults:
        where = f"fault '{f}'"
        if f.start_tick(dt_s) >= (ticks := int(round(duration_s / dt_s))):  # ticks 0 .. ticks - 1 are run
            last = (ticks - 1) * dt_s
            raise ValueError(
                f"{where}: starts at {f.at_s:g} s, at or after the run's end ({duration_s:g} s; its "
                f"last tick is at {last:g} s)"
            )
        named = f.robots
        if named is not None and (unknown := sorted(set(named) - known)):
            raise ValueError(
                f"{where}: no robot {', '.join(map(str, unknown))} in this run; robots are "
                f"{', '.join(map(str, robots))}"
            )
        if (
            f.group == LINK
            and "formation" in f.link_classes
            and named is not None
            and leader_id in named
            and f.link_classes == ("formation",)
        ):
            raise ValueError(f"{where}: robot {leader_id} is the leader; formation links go to followers")
        if f.group == SENSOR and named is not None and leader_id in named:
            raise ValueError(
                f"{where}: robot {leader_id} is the leader; it has no camera in this model (sensor faults apply "
                "to followers; '*' names them all)"
            )
        if f.kind == "partition" and f.param("from") == "leader" and named is not None and leader_id in named:
            raise ValueError(f"{where}: robot {leader_id} is the leader; it cannot be cut off from itself")
        if f.group == PROCESS:
            start, end = f.start_tick(dt_s), f.end_tick(dt_s)
            for s2, e2, other in busy.get(f.target, []):
                # A kill lasts to the end of the run; the others until they end.
                if (e2 is None or start < e2) and (end is None or s2 < end):
                    raise ValueError(f"{where} overlaps '{other}' on the same process")
            busy.setdefault(f.target, []).append((start, end, f))


def past_the_end(faults: Sequence[Fault], duration_s: float, dt_s: float) -> list[str]:
    """Warnings for faults whose window reaches past the run's last tick: they
    are cut there, which a schedule written for a longer run may not mean."""
    ticks = int(round(duration_s / dt_s))
    out = []
    for f in faults:
        end = f.end_tick(dt_s)
        if f.for_s is not None and end is not None and end > ticks:
            kept = (ticks - f.start_tick(dt_s)) * dt_s
            out.append(f"fault '{f}' lasts past the run's end ({duration_s:g} s): it is cut there, after {kept:g} s")
    return out


def parse_all(
    values: Iterable[Fault | str | Mapping[str, Any]] | Fault | str | Mapping[str, Any], where: str = "faults"
) -> tuple[Fault, ...]:
    """The faults, by start time (those that start together in the order
    given). One fault given alone (a string, a table) is one fault, not a
    sequence of letters or keys."""
    if isinstance(values, (str, Mapping, Fault)):
        values = [values]
    out = []
    for i, v in enumerate(values):
        try:
            out.append(Fault.coerce(v))
        except ValueError as exc:
            raise ValueError(f"{where}[{i}]: {exc}") from None
    return tuple(sorted(out, key=lambda f: f.at_s))


def link_faults(faults: Iterable[Fault], link_class: str, robot_id: int) -> tuple[Fault, ...]:
    """The link faults (and partitions) on one directed link of one robot."""
    out = []
    for f in faults:
        if f.group == LINK and link_class in f.link_classes and f.applies_to(robot_id):
            out.append(f)
        elif f.kind == "partition" and f.applies_to(robot_id):
            side = f.param("from")
            if (link_class in ("obs", "cmd") and side in ("world", "both")) or (
                link_class == "formation" and side in ("leader", "both")
            ):
                out.append(f)
    return tuple(out)


def of_robot(faults: Iterable[Fault], group: str, robot_id: int) -> tuple[Fault, ...]:
    return tuple(f for f in faults if f.group == group and f.applies_to(robot_id))


def reference() -> str:
    """The table of every kind and parameter in docs/faults.md (``make docs``)."""
    out = ["| kind | group | target | duration | parameters | what it does |", "|---|---|---|---|---|---|"]
    targets = {
        PROCESS: "`agent-N`, `logger`",
        LINK: "`CLASS[:ROBOTS]`",
        NETWORK: "ROBOTS",
        SENSOR: "ROBOTS",
        ACTUATOR: "ROBOTS",
    }
    for name, k in KINDS.items():
        target = "`agent-N`" if name == "restart" else targets[k.group]
        duration = "required" if k.needs_for else ("none" if not k.allows_for else "optional (none: to the end)")
        params = []
        for pname, p in k.params.items():
            if p.choices:
                rng = " \\| ".join(p.choices)
            else:
                hi = "" if p.high == math.inf else f"{p.high:g}"
                lo = "" if p.low == -math.inf else f"{p.low:g}"
                if lo and hi:
                    rng = f"{'(' if p.open_low else '['}{lo}, {hi}]"
                elif lo:
                    rng = f"{'>' if p.open_low else '>='} {lo}"
                else:
                    rng = "any"
            default = "required" if p.default is None else (f"default {_fmt(p.default)}")
            if pname in k.one_of:
                default = f"one of {'/'.join(k.one_of)}"
            unit = f" {p.unit}" if p.unit else ""
            params.append(f"`{pname}`{unit} {rng}, {default}: {p.doc}")
        out.append(f"| `{name}` | {k.group} | {target} | {duration} | {'<br>'.join(params) or '-'} | {k.doc} |")
    return "\n".join(out) + "\n"


BEGIN, END = "<!-- kinds: generated by make docs -->", "<!-- /kinds -->"


def update_doc(path: str) -> None:
    """Rewrite the table of kinds between the markers of ``path``."""
    from pathlib import Path

    text = Path(path).read_text()
    head, sep, rest = text.partition(BEGIN)
    _, sep2, tail = rest.partition(END)
    if not (sep and sep2):
        raise SystemExit(f"{path}: no {BEGIN} ... {END} markers")
    Path(path).write_text(f"{head}{BEGIN}\n{reference()}{END}{tail}")


if __name__ == "__main__":
    import sys

    update_doc(sys.argv[1] if len(sys.argv) > 1 else "docs/faults.md")
