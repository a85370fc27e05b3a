"""A controller fed a stream of inputs for engine.check, each answer checked
as the follower's role takes it (agents.follower_role) and the world its
command (world.commands): the checks' names, the problems found (one line
each, the first of a kind with a count of the others), and what an answer
must be.
"""

from __future__ import annotations

import collections
import math
import numbers
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from formation_swarm.agents.controller import (
    STATS_VALUES,
    WIRE_VALUES,
    FollowerController,
    FollowerInput,
    FollowerOutput,
    TargetEstimate,
)
from formation_swarm.protocol.messages import EXTRA_NAME, MAX_EXTRAS
from formation_swarm.world.commands import WHEEL_TOLERANCE

# The checks, by the name each problem line starts with (docs/controllers.md, "Check your controller").
BUILD = "build"  # Class(setup) returns
STREAM = "stream"  # the recorded stream answered without raising
OUTPUT = "output"  # each answer a FollowerOutput of numbers, a stop word or None, a mapping of values
FINITE = "finite"  # finite wheel speeds and target
WHEEL_LIMIT = "wheel limit"  # wheel speeds within robot.max_wheel_mps
TELEMETRY = "telemetry"  # the values' own names fit the wire
NO_READING = "no reading"  # reading None: at first and for longer than lost_after_s
SEVERAL_TICKS = "several ticks"  # ticks > 1, dt_s their sum
SLOT_CHANGE = "slot change"  # a new slot mid-stream, slot_moved
NEW_REFERENCE = "new reference"  # another reference mid-stream, new_reference
DETERMINISM = "determinism"  # two instances built alike answer alike
GLOBAL_RANDOM = "global random"  # random's and numpy.random's global states left alone
RESET = "reset"  # reset(), if the class has it: before the first step, and mid-stream to answer as a fresh one
CLOSE = "close"  # close(), if the class has it, returns once a run's inputs are over
PER_ANSWER = (OUTPUT, FINITE, WHEEL_LIMIT, TELEMETRY)  # checked on every answer of every run
KNOWN_NAMES = frozenset(WIRE_VALUES + STATS_VALUES)


class Problems:
    """Problem lines, the first of each (check, kind) kept and the others
    counted; an error raised alike (the same call, error and input) in
    several checks is one line naming them all."""

    def __init__(self) -> None:
        self._first: dict[tuple[str, str], str] = {}
        self._more: collections.Counter[tuple[str, str]] = collections.Counter()
        self._raised: dict[str, tuple[str, str]] = {}  # an error's text -> the first line's key
        self._also: collections.defaultdict[tuple[str, str], list[str]] = collections.defaultdict(list)

    def add(self, check: str, kind: str, text: str) -> None:
        key = (check, kind)
        if key in self._first:
            self._more[key] += 1
        else:
            self._first[key] = f"{check}: {text}"

    def raised(self, check: str, call: str, exc: BaseException, where: str) -> None:
        """``call`` raised ``exc`` ``where`` (at input i of a run) in check ``check``."""
        error = f"{call} raised {one_line(exc)}"
        same = f"{error} at {where.partition(' of ')[0]}"
        if (first := self._raised.get(same)) is not None and first[0] != check:
            self._also[first].append(check)
            return
        self._raised.setdefault(same, (check, call))
        self.add(check, call, f"{error} at {where}")

    def lines(self) -> tuple[str, ...]:
        out = []
        for key, line in self._first.items():
            if n := self._more[key]:
                line += f"; {n} more alike"
            if also := self._also.get(key):
                line += f"; the same in {', '.join(dict.fromkeys(also))}"
            out.append(line)
        return tuple(out)


class Feeder:
    """Runs of inputs fed to controllers, their problems kept in ``problems``."""

    def __init__(self, max_wheel_mps: float) -> None:
        self.max_wheel_mps = max_wheel_mps
        self.problems = Problems()

    def feed(
        self, ctl: FollowerController, inputs: Sequence[FollowerInput], check: str, what: str, *, close: bool = True
    ) -> list[str] | None:
        """``inputs`` fed to ``ctl`` (``prepare()`` after each step and, with
        ``close``, ``close()`` at the end, where it has them) as the run
        ``check`` does; every answer checked. The answers, each as a
        comparable text; None where it raised (said as a problem of ``check``)."""
        problems = self.problems
        prepare = getattr(ctl, "prepare", None)
        answers = []
        for i, inp in enumerate(inputs):
            where = f"input {i} of {what}"
            try:
                out = ctl.step(inp)
            except Exception as exc:  # noqa: BLE001 - a user's controller: what it raises is the problem
                problems.raised(check, "step()", exc, where)
                return None
            for kind, check_of, said, why in answer_problems(out, self.max_wheel_mps):
                problems.add(check_of, kind, f"{said} at {where}{why}")
            answers.append(_text(out))
            if callable(prepare):
                try:
                    prepare()
                except Exception as exc:  # noqa: BLE001 - as in step
                    problems.raised(check, "prepare()", exc, f"{where}, after its step")
                    return None
        if close and callable(hook := getattr(ctl, "close", None)):
            try:
                hook()
            except Exception as exc:  # noqa: BLE001 - as in step
                problems.raised(CLOSE, "close()", exc, f"the end of {what}")
        return answers


Found = tuple[str, str, str, str]  # kind, check, what is wrong, why it matters (": ..." or "")
STOPS = ": the robot would stop for the rest of the run"  # what the role does with it (agents.follower_role)


def answer_problems(out: Any, max_wheel_mps: float) -> Iterator[Found]:
    """What is wrong with one answer."""
    if not isinstance(out, FollowerOutput):
        yield "type", OUTPUT, f"step() returned {_shown(out)}, not a FollowerOutput", STOPS
        return
    limit = max_wheel_mps * (1.0 + WHEEL_TOLERANCE)  # the world's own bound (world.commands)
    for name in ("left_mps", "right_mps"):
        v = getattr(out, name)
        if not _number(v):
            yield name, OUTPUT, f"{name} is {_shown(v)}, not a float", STOPS
        elif not math.isfinite(v):
            yield name, FINITE, f"{name} is {v!r}", STOPS
        elif abs(v) > limit:
            refused = ": the world refuses the command and keeps the robot on its last one until it goes stale"
            yield (
                name,
                WHEEL_LIMIT,
                f"{name} = {float(v):g} m/s, beyond robot.max_wheel_mps = {max_wheel_mps:g}",
                refused,
            )
    if out.stop is not None and not isinstance(out.stop, str):
        yield "stop", OUTPUT, f"stop is {_shown(out.stop)}, not a string or None", STOPS
    yield from _target_problems(out.target)
    yield from _values_problems(out.values)


def _target_problems(target: Any) -> Iterator[Found]:
    if target is None:
        return
    if not isinstance(target, TargetEstimate):
        yield "target", OUTPUT, f"target is {_shown(target)}, not a TargetEstimate or None", STOPS
        return
    xy = (target.x_m, target.y_m)
    if not all(map(_number, xy)):
        yield "target", OUTPUT, f"target's x_m, y_m are {_shown(xy)}, not floats", STOPS
    elif not all(map(math.isfinite, xy)):
        yield "target", FINITE, f"target's x_m, y_m are {xy!r}", ": give target=None when there is no estimate"
    cov = target.cov_m2
    if cov is None:
        return
    if not isinstance(cov, Sequence) or len(cov) != 3 or not all(map(_number, cov)):
        yield "cov", OUTPUT, f"target.cov_m2 is {_shown(cov)}, not (xx, xy, yy) floats or None", STOPS
    elif not all(map(math.isfinite, cov)):
        yield "cov", FINITE, f"target.cov_m2 is {tuple(cov)!r}", ": give cov_m2=None when there is none"


def _values_problems(values: Any) -> Iterator[Found]:
    """Values a mapping of names to numbers (NaN or infinite: "none this
    tick", as docs/controllers.md has it); its own names fit the wire."""
    if not isinstance(values, Mapping):
        yield "values", OUTPUT, f"values is {_shown(values)}, not a mapping of names to floats", STOPS
        return
    own = 0
    for name, v in values.items():
        if not _number(v):
            yield "value", OUTPUT, f"values[{name!r:.40}] is {_shown(v)}, not a float", STOPS
        if name in KNOWN_NAMES:
            continue
        own += 1
        if not isinstance(name, str) or EXTRA_NAME.fullmatch(name) is None:
            why = ": it is not sent (a letter, then letters, digits or _; 1 to 32 characters)"
            yield "name", TELEMETRY, f"value name {name!r:.40}", why
    if own > MAX_EXTRAS:
        yield "names", TELEMETRY, f"{own} values of its own", f": only the first {MAX_EXTRAS} are sent"


def first_difference(a: Sequence[str], b: Sequence[str]) -> int | None:
    """The first step two runs answered differently (or where one of them ended); None: alike."""
    for i, (x, y) in enumerate(zip(a, b, strict=False)):
        if x != y:
            return i
    return None if len(a) == len(b) else min(len(a), len(b))


def one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:200]}" if text else type(exc).__name__


def _number(v: object) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _shown(v: object) -> str:
    return f"{type(v).__name__} {v!r:.60}"


def _text(out: Any) -> str:
    """An answer as text: two answers alike, bit for bit (NaN as NaN), have the same."""
    if not isinstance(out, FollowerOutput):
        return repr(out)
    values = tuple(out.values.items()) if isinstance(out.values, Mapping) else out.values
    return repr((out.left_mps, out.right_mps, out.target, out.stop, values))
