"""What swarm report, compare and export read of a run's summary.json, as
a schema: each key they read and the JSON type of its value. Checked once,
when the summary is read (report.inputs), so the code that reads it can
take the types as given.

A schema is a type (``NUM``, ``INT``, ``STR``, ``BOOL``, ``SCALAR``), an
object's keys (a dict: each key may be absent or null, others are not
read), ``Each(schema)`` (an object whose every value is one) or
``[schema]`` (an array, each item one; null items are refused: the code
reads each)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Kind:
    """A JSON scalar type: its Python types and its name in an error."""

    types: tuple[type, ...]
    name: str

    def holds(self, value: Any) -> bool:
        return isinstance(value, self.types) and (bool in self.types or not isinstance(value, bool))


@dataclass(frozen=True)
class Each:
    """An object keyed by anything (a robot id, a link), every value ``of``."""

    of: Any


NUM = Kind((int, float), "a number")
INT = Kind((int,), "an integer")
STR = Kind((str,), "a string")
BOOL = Kind((bool,), "true or false")
SCALAR = Kind((str, int, float, bool), "a string or a number")  # only ever written into text

METRICS = {k: NUM for k in ("rms_m", "max_m", "turn_rms_m", "straight_rms_m", "turn_mean_lag_m", "max_ahead_m")}
FOLLOWER = {
    **METRICS,
    "acquired": BOOL,
    "seen_ticks": INT,
    "frames": INT,
    "until_stopped": {"time_s": NUM, "rms_m": NUM, "max_m": NUM},
}
RECOVERY = {
    "watched": [SCALAR],
    **{k: NUM for k in ("since_s", "resolution_s", "first_below_after_s", "bound_m", "settled_after_s")},
    **{k: NUM for k in ("max_in_window_m", "window_s")},
}
FAULT = {
    "fault": SCALAR,
    "kind": SCALAR,
    "target": SCALAR,
    "at_s": NUM,
    "for_s": NUM,
    "start_tick": INT,
    "end_tick": INT,
    "counts": Each(NUM),
    "counts_partial_for": [SCALAR],
    "events": [{"event": SCALAR, "robot": SCALAR, "tick": INT, "time_s": NUM}],
    "recoveries": [RECOVERY],
}
EVENT = {
    "event": SCALAR,
    "process": SCALAR,
    "sim_time_s": NUM,
    "tick": INT,
    "code": INT,
    "robots": [SCALAR],
}
SUMMARY = {
    "run_id": STR,
    **{k: SCALAR for k in ("scenario", "mode", "ended", "end_reason", "failure", "recording", "recording_gap")},
    **{k: INT for k in ("seed", "ticks", "ticks_seen", "exit_code", "collisions", "obstacle_collisions")},
    **{k: INT for k in ("lockstep_misses", "rejected_total", "drops_total")},
    **{k: NUM for k in ("sim_time_s", "ended_at_s", "min_distance_m", "robot_diameter_m")},
    "interrupted": BOOL,
    "timed_out": BOOL,
    "laws": {"leader": SCALAR, "followers": Each(SCALAR)},
    "followers": Each(FOLLOWER),
    "parts": {
        "logger": {
            "target_errors": Each(
                {
                    **{k: NUM for k in ("measured_rms_m", "ekf_rms_m", "ekf_rms_seen_m")},
                    **{"nees_mean": NUM, "nees_ticks": INT, "nees_beyond_99": NUM},
                }
            )
        },
        "world": {"logger_lost": {"time_s": NUM, "tick": INT}},
    },
    "formation_events": [{"tick": INT, "time_s": NUM, "robot": SCALAR, "formation": SCALAR}],
    "faults": [FAULT],
    "events": [EVENT],
    "deaths": [{"robot": SCALAR, "tick": INT, "time_s": NUM}],
    "contacts": [{"robots": [SCALAR], "robot": SCALAR, "obstacle": SCALAR, "time_s": NUM}],
    "rejected": Each(Each(NUM)),
    "link_totals": Each({"partitioned": INT}),
    "scenario_warnings": [STR],
}


def check(value: Any, schema: Any, where: str = "") -> None:
    """``value`` against ``schema``; ValueError naming the first key at fault
    ("followers.2.rms_m must be a number, got a string"). The schema is
    shallow, so is this recursion, whatever the value's depth."""
    if isinstance(schema, Kind):
        if not schema.holds(value):
            raise ValueError(f"{where or 'the summary'} must be {schema.name}, got {json_type(value)}")
        return
    if isinstance(schema, list):
        _check_array(value, schema[0], where)
    elif not isinstance(value, Mapping):
        raise ValueError(f"{where or 'the summary'} must be an object, got {json_type(value)}")
    elif isinstance(schema, Each):
        for k, v in value.items():
            if v is not None:
                check(v, schema.of, f"{where}.{k}")
    else:
        for k, sub in schema.items():
            if value.get(k) is not None:
                check(value[k], sub, f"{where}.{k}" if where else k)


def _check_array(value: Any, item: Any, where: str) -> None:
    if not isinstance(value, list):
        raise ValueError(f"{where} must be an array, got {json_type(value)}")
    for i, x in enumerate(value):
        if x is None:
            raise ValueError(f"{where}[{i}] must not be null")
        check(x, item, f"{where}[{i}]")


def json_type(value: Any) -> str:
    """A value's JSON type, as an error says it."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return f"the number {value!r:.20}"
    if isinstance(value, str):
        return f"the string {value!r:.40}"
    return "an array" if isinstance(value, list) else "an object"
