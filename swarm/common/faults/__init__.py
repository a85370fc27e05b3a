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
launcher each take the part of the schedule that is theirs. The kinds and
their parameters are in ``fault_kinds``, the checks of a schedule against
its run in ``fault_schedule``, the table of docs/faults.md in ``faults_doc``.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from formation_swarm.common.faults.kinds import (
    ACTUATOR,
    ALL_LINKS,
    KINDS,
    LINK,
    LINK_CLASSES,
    NETWORK,
    PROCESS,
    SENSOR,
    seconds,
    value_text,
)

# The grammar's public face: the kinds' groups are named from here too.
__all__ = [
    "ACTUATOR",
    "KINDS",
    "LINK",
    "LINK_CLASSES",
    "NETWORK",
    "PROCESS",
    "SENSOR",
    "Fault",
    "link_faults",
    "of_robot",
    "parse_all",
    "seconds",
]


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
        out += [f"{k}={value_text(v)}" for k, v in self.params]
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
