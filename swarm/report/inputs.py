"""A run folder's summary.json and scenario.toml, read as input that may be
hostile: a size limit, JSON without NaN or infinities, a depth limit, the
summary's fields checked against what the report reads (report.schema) and
the scenario checked by the scenario loader. Each refusal is one
ValueError naming the file and what is wrong with it."""

from __future__ import annotations

import json
import tomllib
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.report.schema import SUMMARY, check
from formation_swarm.spec.keys import MAX_DEPTH, ScenarioError, ScenarioWarning

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

# Far above what a run writes: a 500-robot run of an hour writes a summary of
# a few MB; a scenario as run is a few kB (its robots, obstacles and faults).
MAX_SUMMARY_BYTES = 64 * 2**20
MAX_SCENARIO_BYTES = 4 * 2**20
INT_BITS = 64  # JSON's integers as a run writes them: seeds, ticks, counts
UNCHECKED_WHEEL_MPS = 1e9  # robot.max_wheel_mps for a scenario of a user's law: no check reads it


class _Refused(ValueError):
    """A JSON value no run writes, refused as it is parsed."""


def read_bounded(path: Path, limit: int) -> bytes:
    """A regular file's bytes; ValueError for anything else (a folder, a pipe
    that would block the read) or a file over ``limit`` bytes."""
    if not path.is_file():
        raise ValueError(f"{path}: not a regular file")
    with path.open("rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ValueError(f"{path}: larger than {limit // 2**20} MiB, more than any run writes")
    return data


def read_summary(path: Path) -> dict[str, Any]:
    """summary.json as a dict whose fields the report reads have their types
    (report.schema.SUMMARY); ValueError naming the file and the fault."""
    data = read_bounded(path, MAX_SUMMARY_BYTES)
    try:
        summary = json.loads(data, parse_constant=_constant, parse_float=_float, parse_int=_int)
    except _Refused as exc:
        raise ValueError(f"{path}: {exc}") from None
    except RecursionError:  # json recurses once per level
        raise ValueError(f"{path}: arrays or objects nested more than {MAX_DEPTH} deep") from None
    except ValueError as exc:  # not JSON, or not UTF-8
        raise ValueError(f"{path} is not valid JSON: {' '.join(str(exc).split())}") from None
    if _too_deep(summary):
        raise ValueError(f"{path}: arrays or objects nested more than {MAX_DEPTH} deep")
    if not isinstance(summary, dict) or not isinstance(summary.get("run_id"), str):
        raise ValueError(f"{path} is not a run summary (a JSON object with the run's run_id)")
    try:
        check(summary, SUMMARY)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return summary


def read_scenario(path: Path) -> tuple[dict[str, Any], Scenario] | None:
    """scenario.toml as its tables and as the loader reads it (None: the
    folder has none); ValueError naming the file and the fault. No module
    the file names is imported (``for_the_report``)."""
    from formation_swarm.spec.checking import check_values
    from formation_swarm.spec.scenario import from_dict

    if not path.exists() and not path.is_symlink():
        return None
    data = read_bounded(path, MAX_SCENARIO_BYTES)
    try:
        raw = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path} is not a scenario: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except RecursionError:  # tomllib recurses once per level of arrays and inline tables
        raise ValueError(f"{path}: arrays or inline tables nested more than {MAX_DEPTH} deep") from None
    except ValueError as exc:  # TOMLDecodeError, or an integer of more digits than Python reads
        raise ValueError(f"{path} is not valid TOML: {exc}") from None
    try:
        check_values(raw)  # NaN, infinities, nesting, integers past 64 bits, in every table
        with warnings.catch_warnings():  # the loader's warnings are the run's: summary.json lists them
            warnings.simplefilter("ignore", ScenarioWarning)
            return raw, from_dict(for_the_report(raw))
    except ScenarioError as exc:
        raise ValueError(f"{path}: not a scenario this version reads: {exc}") from None


def for_the_report(raw: dict[str, Any]) -> dict[str, Any]:
    """The scenario's tables as the loader checks them for a report: a law or
    a leader's policy that is not built in is left out with its params, so
    that no module the file names is imported (the report draws no
    controller); the wheel limit, which only the built-in ones' checks read,
    is then lifted, as the run's own checks skipped it for them."""
    from formation_swarm.agents.params import LAWS
    from formation_swarm.spec.keys import LEADER_KEYS

    def trimmed(table: Any, name: str, built_in: Any) -> Any:
        if isinstance(table, dict) and name in table and table[name] not in built_in:
            left_out.append(table[name])
            return {k: v for k, v in table.items() if k not in (name, "params")}
        return table

    left_out: list[Any] = []
    out = {**raw, "controller": trimmed(raw.get("controller"), "law", LAWS)}
    if isinstance(raw.get("followers"), dict):
        out["followers"] = {rid: trimmed(t, "law", LAWS) for rid, t in raw["followers"].items()}
    policy = LEADER_KEYS.get("policy")  # a scenario of a version without policies has none
    out["leader"] = trimmed(raw.get("leader"), "policy", (getattr(policy, "default", None),))
    out = {k: v for k, v in out.items() if k in raw}  # no table the file has not
    robot = raw.get("robot", {})
    if left_out and isinstance(robot, dict):
        out["robot"] = {**robot, "max_wheel_mps": UNCHECKED_WHEEL_MPS}
    return out


def _constant(name: str) -> Any:
    raise _Refused(f"holds {name}, which no run writes (a number must be finite)")


def _float(text: str) -> float:
    x = float(text)
    if x in (float("inf"), float("-inf")):
        raise _Refused(f"holds {text[:30]}, a number too large for a float (a number must be finite)")
    return x


def _int(text: str) -> int:
    if len(text) > 21:  # 2**64 has 20 digits; a longer one is refused before Python converts it
        raise _Refused(f"holds an integer of {len(text)} digits, larger than any run writes ({INT_BITS} bits)")
    n = int(text)
    if not -(2**INT_BITS) < n < 2**INT_BITS:
        raise _Refused(f"holds the integer {text}, larger than any run writes ({INT_BITS} bits)")
    return n


def _too_deep(value: Any) -> bool:
    """Whether ``value`` nests arrays or objects more than MAX_DEPTH deep;
    walked without recursion."""
    stack: list[tuple[Any, int]] = [(value, 1)] if isinstance(value, (dict, list)) else []
    while stack:
        v, depth = stack.pop()
        if depth > MAX_DEPTH:
            return True
        items = v.values() if isinstance(v, dict) else v
        stack.extend((x, depth + 1) for x in items if isinstance(x, (dict, list)))
    return False
