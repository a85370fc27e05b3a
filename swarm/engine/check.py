"""A follower controller checked before it flies, as Gymnasium's ``check_env``
checks an environment: ``check_controller("my_controller:Mine")`` returns
its problems, one line each, naming the check (empty: it passes).

The law is built as ``swarm run`` builds it (the scenario loaded with the
law and its params on one follower, its ``ControllerSetup`` and
agents.follower.make_controller), then fed what that follower's controller
received in a real run: the scenario's first ticks flown by the engine
with the built-in law, recorded at the controller's seam. Fresh instances
get that stream as it came, with no reading, several ticks at once, a slot
moved, a new reference; two of them, with the global random states seeded
apart, must answer it alike and leave those states alone
(engine.check_feed checks each answer). docs/controllers.md says what each
check means.
"""

from __future__ import annotations

import dataclasses
import functools
import random
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from formation_swarm.agents.controller import ControllerSetup, FollowerController, FollowerInput
from formation_swarm.agents.follower import LAWS, law_class, make_controller
from formation_swarm.agents.formation import Slot
from formation_swarm.agents.geometry import Point
from formation_swarm.agents.laws import LawError, check_class, declared_params
from formation_swarm.engine.check_feed import (
    BUILD,
    CLOSE,
    DETERMINISM,
    GLOBAL_RANDOM,
    NEW_REFERENCE,
    NO_READING,
    PER_ANSWER,
    RESET,
    SEVERAL_TICKS,
    SLOT_CHANGE,
    STREAM,
    Feeder,
    Problems,
    first_difference,
    one_line,
)
from formation_swarm.engine.core import Engine
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.checking import check_table
from formation_swarm.spec.keys import NUM, Key, ScenarioWarning

__all__ = ["CheckReport", "check_controller", "run_checks"]

RECORD_TICKS = 700  # 35 s of fig11_obstacles: both of its formation changes (ticks 393 and 609)
RECORD_LAW = "fuzzy"  # what the recorded follower flies: a law that holds its slot
SEVERAL = 3  # ticks per step in "several ticks"
RANDOM_SEEDS = (1, 2)  # the global random states' seeds in the two determinism runs: apart on purpose


@dataclasses.dataclass(frozen=True)
class CheckReport:
    """What :func:`run_checks` found: the law's name, the checks run, the problems (one line each)."""

    law: str
    checks: tuple[str, ...]
    problems: tuple[str, ...]


def check_controller(
    law: str | type,
    params: Mapping[str, Any] | None = None,
    *,
    scenario: str | Path = "fig11_obstacles",
    robot: int | None = None,
    seed: int = 0,
) -> list[str]:
    """The problems of the follower controller ``law`` (``"module:Class"``, an
    entry point's name or the class itself) with ``params`` (as
    ``[followers.ID.params]``), one line each, naming the check; empty: it
    passes. ``robot``: the follower it flies (None: the scenario's first);
    ``seed``: the recorded run's. A law that cannot be built as ``swarm run``
    builds it (no such module or class, a bad or unknown parameter, a
    scenario or robot that is not) raises ValueError."""
    return list(run_checks(law, params, scenario=scenario, robot=robot, seed=seed).problems)


def run_checks(
    law: str | type,
    params: Mapping[str, Any] | None = None,
    *,
    scenario: str | Path = "fig11_obstacles",
    robot: int | None = None,
    seed: int = 0,
    ticks: int = RECORD_TICKS,
) -> CheckReport:
    """:func:`check_controller` with the checks it ran; ``ticks``: the recorded stream's length."""
    if isinstance(ticks, bool) or not isinstance(ticks, int) or ticks < 2:
        raise ValueError(f"ticks must be an integer >= 2, got {ticks!r}")
    built = _Built(law, params or {}, scenario, robot)
    stream = recorded(scenario, seed, built.robot, ticks)
    feeder = Feeder(built.setup.max_wheel_mps)
    checks = [BUILD, STREAM, *PER_ANSWER, NO_READING, SEVERAL_TICKS, SLOT_CHANGE, NEW_REFERENCE]
    checks += [DETERMINISM, GLOBAL_RANDOM]
    saved = random.getstate(), np.random.get_state()
    try:
        first = _seeded_run(built, stream, (RANDOM_SEEDS[0], STREAM), feeder)
        if first is None:  # not built: nothing else can run
            return CheckReport(built.name, (BUILD,), feeder.problems.lines())
        second = _seeded_run(built, stream, (RANDOM_SEEDS[1], DETERMINISM), feeder)
        _compare(first, second, feeder.problems)
        _variants(built, stream, feeder)
        if callable(getattr(built.cls, "reset", None)):
            checks.append(RESET)
            _reset(built, stream, first[0], feeder)
        if callable(getattr(built.cls, "close", None)):
            checks.append(CLOSE)
    finally:
        random.setstate(saved[0])
        np.random.set_state(saved[1])
    return CheckReport(built.name, tuple(checks), feeder.problems.lines())


# -- the law, built as swarm run builds it ------------------------------------------------


class _Built:
    """Law ``law`` with ``params`` for one follower of ``scenario``, as
    ``swarm run`` loads it: ``make()`` is a fresh controller (or raises what
    its class raises)."""

    def __init__(self, law: str | type, params: Mapping[str, Any], scenario: str | Path, robot: int | None) -> None:
        if not isinstance(params, Mapping):
            raise ValueError(f"params must map parameter names to values, got {type(params).__name__}")
        sc = _load(scenario, {})
        followers = list(sc.follower_ids)
        rid = followers[0] if robot is None else robot
        if rid not in followers:
            raise ValueError(f"robot {rid!r} is not a follower of {sc.name}; its followers are {followers}")
        self.robot = rid
        where = f"followers.{rid}"
        ref = _reference(law)
        self._direct: type | None = None  # a class built by hand, not by name
        if ref is not None:  # by name: the scenario checks it and its params, as for swarm run
            overrides = {f"{where}.law": ref, **{f"{where}.params.{k}": v for k, v in params.items()}}
            sc = _load(scenario, overrides)
            fp, self.name, self.cls = sc.followers[rid], ref, law_class(ref)
        else:  # a class no module:Class reaches (one made in a function): its params checked alike
            self._direct = self.cls = law  # type: ignore[assignment]
            self.name = f"{law.__module__}:{law.__qualname__}"  # type: ignore[union-attr]
            fp = dataclasses.replace(sc.followers[rid], law=self.name, law_params=_checked(law, params, where))
        slot = sc.formation_by_code(sc.code_of(sc.leader.formation)).slots[rid]
        self.setup = ControllerSetup(robot_id=rid, params=fp, slot=slot, max_wheel_mps=sc.max_wheel_mps)
        self.scenario = sc

    def make(self) -> FollowerController:
        if self._direct is None:
            return make_controller(self.setup)  # as the agent builds it (nodes.agent.setup)
        params = {**declared_params(self._direct), **dict(self.setup.params.law_params)}
        controller: FollowerController = self._direct(dataclasses.replace(self.setup, law_params=params))
        return controller


def _checked(cls: type, params: Mapping[str, Any], where: str) -> tuple[tuple[str, Any], ...]:
    """``params`` checked against what ``cls`` declares, as spec.controllers checks a law's."""
    name = f"{cls.__module__}:{cls.__qualname__}"
    try:
        declared = declared_params(check_class(cls, name), name)
    except LawError as exc:
        raise ValueError(f"{where}.law: {exc}") from None
    schema = {k: Key(NUM if isinstance(d, float) else type(d), d, "") for k, d in declared.items()}
    checked = check_table(dict(params), f"{where}.params", schema)
    return tuple((k, float(v) if isinstance(declared[k], float) else v) for k, v in checked.items())


def _reference(law: object) -> str | None:
    """The name a scenario can give ``law`` by, or None for a class that no
    ``module:Class`` reaches (made in a function, say)."""
    if isinstance(law, str):
        return law
    if not isinstance(law, type):
        raise ValueError(f"law must be a name (module:Class) or a class, got {type(law).__name__} {law!r:.60}")
    import importlib

    ref = f"{law.__module__}:{law.__qualname__}"
    try:
        found = getattr(importlib.import_module(law.__module__), law.__qualname__, None)
    except Exception:  # noqa: BLE001 - a module that cannot be imported again: the class itself is used
        return None
    return ref if found is law else None


def _load(scenario: str | Path, overrides: Mapping[str, Any]) -> scenario_mod.Scenario:
    with warnings.catch_warnings():  # the scenario's own warnings are not the controller's
        warnings.simplefilter("ignore", ScenarioWarning)
        return scenario_mod.load(scenario, overrides)


# -- the recorded stream ---------------------------------------------------------------


def recorded(scenario: str | Path, seed: int, robot: int, ticks: int) -> tuple[FollowerInput, ...]:
    """What follower ``robot``'s controller received in the first ``ticks``
    ticks of ``scenario`` flown by the engine with seed ``seed``, every
    follower flying a built-in law (RECORD_LAW where the scenario names
    another). Recorded once per process for the same scenario, seed and ticks."""
    stream = _recorded(scenario, seed, ticks).get(robot, ())
    if len(stream) < 2:
        raise ValueError(f"{scenario}: robot {robot}'s controller got {len(stream)} inputs: too short a run to check")
    return stream


@functools.lru_cache(maxsize=4)
def _recorded(scenario: str | Path, seed: int, ticks: int) -> dict[int, tuple[FollowerInput, ...]]:
    """Every follower's inputs of :func:`recorded`, by robot id."""
    sc = _load(scenario, {})
    overrides: dict[str, Any] = {}
    for rid in sc.follower_ids:
        if sc.followers[rid].law not in LAWS:
            overrides |= {f"followers.{rid}.law": RECORD_LAW, f"followers.{rid}.params": {}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScenarioWarning)
        engine = Engine(scenario, seed=seed, overrides=overrides)
    inputs: dict[int, list[FollowerInput]] = {rid: [] for rid in sc.follower_ids}
    for _ in range(ticks):
        if not engine.step():
            break
        for rid, inp in engine.inputs.items():  # what each controller got at the tick just run
            inputs[rid].append(inp)
    return {rid: tuple(got) for rid, got in inputs.items()}


# -- the runs --------------------------------------------------------------------------


def _seeded_run(
    built: _Built, stream: Sequence[FollowerInput], seeded: tuple[int, str], feeder: Feeder
) -> tuple[list[str] | None, list[str]] | None:
    """A fresh controller built and fed ``stream`` as check ``seeded[1]``,
    the global random states seeded with ``seeded[0]``: its answers (None if
    it raised) and the global states it drew from; None if it could not be built."""
    seed, check = seeded
    random.seed(seed)
    np.random.seed(seed)
    before = random.getstate(), np.random.get_state()
    ctl = _make(built, check, feeder.problems)
    if ctl is None:
        return None
    answers = feeder.feed(ctl, stream, check, "the recorded stream")
    used = []
    if random.getstate() != before[0]:
        used.append("random")
    if not _same_np_state(before[1], np.random.get_state()):
        used.append("numpy.random")
    return answers, used


def _compare(
    first: tuple[list[str] | None, list[str]], second: tuple[list[str] | None, list[str]] | None, problems: Problems
) -> None:
    """The determinism runs: alike, and neither drew from a global random state."""
    one, two = first[0], None if second is None else second[0]
    if one is not None and two is not None and (i := first_difference(one, two)) is not None:
        a, b = (run[i][:60] if i < len(run) else "nothing" for run in (one, two))
        problems.add(
            DETERMINISM,
            "differ",
            f"two instances built alike answered input {i} of the recorded stream differently ({a} vs {b}): "
            "draw from a generator seeded from the setup",
        )
    for name in dict.fromkeys([*first[1], *(second[1] if second is not None else ())]):
        problems.add(GLOBAL_RANDOM, name, f"it draws from {name}'s global state: seed a generator of its own")


def _same_np_state(a: Any, b: Any) -> bool:
    return a[0] == b[0] and np.array_equal(a[1], b[1]) and tuple(a[2:]) == tuple(b[2:])


def _make(built: _Built, check: str, problems: Problems) -> FollowerController | None:
    """A fresh controller, reset() as its agent resets it before its first step; None if either raised."""
    try:
        ctl = built.make()
    except Exception as exc:  # noqa: BLE001 - a user's class: what it raises is the problem
        problems.add(BUILD, "raised", f"{built.name}(setup) raised {one_line(exc)} (building it for {check!r})")
        return None
    hook = getattr(ctl, "reset", None)
    if callable(hook):
        try:
            hook()
        except Exception as exc:  # noqa: BLE001 - as in building it
            problems.add(RESET, "raised first", f"reset() raised {one_line(exc)} before the first step ({check!r})")
            return None
    return ctl


def _variants(built: _Built, stream: Sequence[FollowerInput], feeder: Feeder) -> None:
    """The stream changed as a run changes it, each fed to a fresh controller."""
    mid = len(stream) // 2
    sc, rid = built.scenario, built.robot
    lost = max(2, round(built.setup.params.lost_after_s / sc.dt_s) + 10)  # past lost_after_s
    unseen = [dataclasses.replace(inp, reading=None) for inp in stream]
    no_reading = [*unseen[:10], *stream[10:mid], *unseen[mid : mid + lost], *stream[mid + lost :]]
    variants = [
        (NO_READING, "the stream with no reading at first and for a while mid-stream", no_reading),
        (SEVERAL_TICKS, f"the stream {SEVERAL} ticks a step", _grouped(stream, SEVERAL)),
    ]
    slot = stream[mid].slot
    moved = _other_slot(sc, rid, slot)
    variants.append((SLOT_CHANGE, "the stream with its slot moved mid-stream", _with_slot(stream, mid, moved)))
    others = [r for r in sc.robots if r not in (rid, slot.reference)]
    if others:
        new = Slot(reference=others[0], offset=slot.offset)
        variants.append((NEW_REFERENCE, "the stream with a new reference mid-stream", _with_slot(stream, mid, new)))
    for check, what, inputs in variants:
        if (ctl := _make(built, check, feeder.problems)) is not None:
            feeder.feed(ctl, inputs, check, what)


def _reset(built: _Built, stream: Sequence[FollowerInput], fresh: list[str] | None, feeder: Feeder) -> None:
    """reset() mid-stream, then the stream again: answered as a fresh controller answers it."""
    if fresh is None or (ctl := _make(built, RESET, feeder.problems)) is None:
        return
    if feeder.feed(ctl, stream[: len(stream) // 2], RESET, "the stream's first half", close=False) is None:
        return
    try:
        ctl.reset()  # type: ignore[attr-defined]
    except Exception as exc:  # noqa: BLE001 - as in step
        feeder.problems.add(RESET, "raised", f"reset() raised {one_line(exc)} after the stream's first half")
        return
    again = feeder.feed(ctl, stream, RESET, "the stream after reset()")
    if again is not None and (i := first_difference(fresh, again)) is not None:
        feeder.problems.add(
            RESET, "differ", f"after reset() it answered input {i} of the stream unlike a fresh controller"
        )


def _grouped(stream: Sequence[FollowerInput], n: int) -> list[FollowerInput]:
    """``n`` ticks a step: each step the last of ``n`` inputs, its flags and times those of all ``n``."""
    out = []
    for i in range(0, len(stream) - n + 1, n):
        group = stream[i : i + n]
        out.append(
            dataclasses.replace(
                group[-1],
                slot_moved=any(g.slot_moved for g in group),
                new_reference=any(g.new_reference for g in group),
                ticks=sum(g.ticks for g in group),
                dt_s=sum(g.dt_s for g in group),
            )
        )
    return out


def _with_slot(stream: Sequence[FollowerInput], at: int, slot: Slot) -> list[FollowerInput]:
    """The stream with ``slot`` from step ``at`` on, flagged there as a formation change flags it."""
    moved, new_ref = slot.offset != stream[at].slot.offset, slot.reference != stream[at].slot.reference
    out = list(stream[:at])
    out.append(dataclasses.replace(stream[at], slot=slot, slot_moved=moved, new_reference=new_ref))
    out += [dataclasses.replace(inp, slot=slot, slot_moved=False, new_reference=False) for inp in stream[at + 1 :]]
    return out


def _other_slot(sc: scenario_mod.Scenario, rid: int, slot: Slot) -> Slot:
    """Another of the scenario's slots of robot ``rid`` behind the same
    reference, or ``slot`` moved 1 m to the side where it has none."""
    for code in range(len(sc.formation_names)):
        s = sc.formation_by_code(code).slots.get(rid)
        if s is not None and s.reference == slot.reference and tuple(s.offset) != tuple(slot.offset):
            return Slot(reference=s.reference, offset=Point(float(s.offset[0]), float(s.offset[1])))
    return Slot(reference=slot.reference, offset=Point(float(slot.offset[0]) + 1.0, float(slot.offset[1])))
