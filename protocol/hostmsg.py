"""What a launcher and a machine's ``swarm host`` say to each other.

A launcher queries ``HostKeys(name).ctl`` with a :class:`HostRequest`; the
host answers one :class:`HostReply`. Both are msgpack maps with the field
names below; decoding refuses (DecodeError, with a countable reason) a payload
that is too big, not a map, has an unknown or missing field, a field of the
wrong type or out of bounds. Each request carries the package version of the
sender: a host refuses one from another version, since its agents would not
run the same code as the launcher's world (a lockstep run would not be the
same run), and says so in ``error``.

ops::

    info     -> hostname, cores, free_mem_mb, robots it may run, time_unix, running
    start    run, process (agent-N or agent-N.k), scenario (TOML text), user,
             password (the agent's login for this run), world_grace_s,
             lockstep (the run's mode: its telemetry waits for the logger
             instead of being dropped) -> pid
    signal   run, process, action (kill, freeze, thaw, term) -> ok
    poll     run -> processes: [name, pid, exit code or None] of the run
    collect  run, process -> code, log (its tail), stats (its --stats JSON text)
    end      run -> every process of the run stopped (SIGTERM, then SIGKILL), ok
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import msgpack

from formation_swarm.protocol.codec import DecodeError
from formation_swarm.protocol.keys import MAX_ROBOT_ID, check_run_id

# Below the 40 KiB every node lets through (protocol.session), headers included.
MAX_HOST_MESSAGE_BYTES = 36 * 1024
MAX_SCENARIO_BYTES = 24 * 1024
MAX_LOG_BYTES = 12 * 1024  # the tail of an agent's log a reply carries
MAX_STATS_BYTES = 20 * 1024
MAX_TEXT = 512  # error messages, names, versions
MAX_PROCESSES = 256
OPS = ("info", "start", "signal", "poll", "collect", "end")
ACTIONS = ("kill", "freeze", "thaw", "term")
_PROCESS = re.compile(r"^agent-([1-9][0-9]{0,4})(\.[0-9]{1,4})?$")


def process_robot(process: str) -> int | None:
    """``agent-3`` / ``agent-3.2`` (a restart) -> 3; None for anything else."""
    m = _PROCESS.match(process) if isinstance(process, str) else None
    if m is None or int(m.group(1)) > MAX_ROBOT_ID:
        return None
    return int(m.group(1))


def _text(limit: int) -> Any:
    def check(name: str, v: Any) -> str:
        if type(v) is not str:
            raise DecodeError("wrong type", f"{name} must be a string, got {type(v).__name__}")
        if len(v.encode()) > limit:
            raise DecodeError("oversized", f"{name} is longer than {limit} bytes")
        return v

    return check


def _int(lo: int, hi: int, optional: bool = False) -> Any:
    def check(name: str, v: Any) -> int | None:
        if v is None and optional:
            return None
        if type(v) is not int:
            raise DecodeError("wrong type", f"{name} must be an integer, got {type(v).__name__}")
        if not lo <= v <= hi:
            raise DecodeError("out of range", f"{name}={v} is not in [{lo}, {hi}]")
        return v

    return check


def _float(lo: float, hi: float) -> Any:
    def check(name: str, v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise DecodeError("wrong type", f"{name} must be a number, got {type(v).__name__}")
        if not (math.isfinite(v) and lo <= v <= hi):
            raise DecodeError("out of range", f"{name}={v} is not in [{lo:g}, {hi:g}]")
        return float(v)

    return check


def _bool(name: str, v: Any) -> bool:
    if type(v) is not bool:
        raise DecodeError("wrong type", f"{name} must be true or false, got {type(v).__name__}")
    return v


def _robots(name: str, v: Any) -> tuple[int, ...] | None:
    if v is None:
        return None
    if not isinstance(v, list) or len(v) > MAX_PROCESSES:
        raise DecodeError("wrong type", f"{name} must be a list of at most {MAX_PROCESSES} robot ids or None")
    return tuple(_int(1, MAX_ROBOT_ID)(name, r) for r in v)


def _processes(name: str, v: Any) -> tuple[tuple[str, int, int | None], ...]:
    if not isinstance(v, list) or len(v) > MAX_PROCESSES:
        raise DecodeError("wrong type", f"{name} must be a list of at most {MAX_PROCESSES} processes")
    out = []
    for item in v:
        if not isinstance(item, list) or len(item) != 3:
            raise DecodeError("wrong type", f"{name}: each process is [name, pid, exit code or None]")
        proc = _text(40)(name, item[0])
        if process_robot(proc) is None:
            raise DecodeError("out of range", f"{name}: {proc[:40]!r} is not agent-N")
        out.append((proc, _int(0, 2**31)(name, item[1]), _int(-255, 255, optional=True)(name, item[2])))
    return tuple(out)


class _Map:
    """A frozen dataclass sent as a msgpack map of its fields; ``CHECKS`` maps
    each field to its checker."""

    CHECKS: ClassVar[dict[str, Any]] = {}

    def to_bytes(self) -> bytes:
        data = {f.name: getattr(self, f.name) for f in fields(self)}  # type: ignore[arg-type]
        for k, v in data.items():
            if isinstance(v, tuple):
                data[k] = [list(x) if isinstance(x, tuple) else x for x in v]
        out = msgpack.packb(data, use_bin_type=True)
        if len(out) > MAX_HOST_MESSAGE_BYTES:
            raise ValueError(f"{type(self).__name__} of {len(out)} bytes is above {MAX_HOST_MESSAGE_BYTES}")
        return out

    @classmethod
    def _decode(cls, payload: bytes) -> dict[str, Any]:
        if len(payload) > MAX_HOST_MESSAGE_BYTES:
            raise DecodeError("oversized", f"{len(payload)} bytes > {MAX_HOST_MESSAGE_BYTES}")
        try:
            raw = msgpack.unpackb(payload, raw=False, strict_map_key=True, max_array_len=MAX_PROCESSES * 4)
        except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError) as exc:
            raise DecodeError("not msgpack", type(exc).__name__) from None
        if not isinstance(raw, dict):
            raise DecodeError("wrong type", f"{cls.__name__} must be a msgpack map")
        unknown = sorted(set(raw) - set(cls.CHECKS))
        if unknown:
            raise DecodeError("unknown field", f"{cls.__name__} has no field {str(unknown[0])[:40]!r}")
        missing = [n for n in cls.CHECKS if n not in raw]
        if missing:
            raise DecodeError("missing field", f"{cls.__name__} needs {missing[0]}")
        return {n: check(n, raw[n]) for n, check in cls.CHECKS.items()}


@dataclass(frozen=True)
class HostRequest(_Map):
    op: str
    version: str  # formation_swarm.__version__ of the sender
    run: str = ""
    process: str = ""
    action: str = ""
    scenario: str = ""
    user: str = ""
    password: str = ""
    world_grace_s: float = 1.0
    sent_unix: float = 0.0  # the sender's clock (swarm doctor compares it)
    lockstep: bool = False

    CHECKS: ClassVar[dict[str, Any]] = {
        "op": _text(16),
        "version": _text(64),
        "run": _text(64),
        "process": _text(40),
        "action": _text(16),
        "scenario": _text(MAX_SCENARIO_BYTES),
        "user": _text(32),
        "password": _text(128),
        "world_grace_s": _float(0.0, 3600.0),
        "sent_unix": _float(0.0, 1e11),
        "lockstep": _bool,
    }

    @classmethod
    def from_bytes(cls, payload: bytes) -> HostRequest:
        req = cls(**cls._decode(payload))
        if req.op not in OPS:
            raise DecodeError("unknown op", f"{req.op[:16]!r}; ops: {', '.join(OPS)}")
        if req.op != "info":
            try:
                check_run_id(req.run)
            except ValueError:
                raise DecodeError("bad run id", repr(req.run[:64])) from None
        if req.op in ("start", "signal", "collect") and process_robot(req.process) is None:
            raise DecodeError("bad process", f"{req.process[:40]!r} is not agent-N or agent-N.k")
        if req.op == "signal" and req.action not in ACTIONS:
            raise DecodeError("bad action", f"{req.action[:16]!r}; actions: {', '.join(ACTIONS)}")
        if req.op == "start" and not req.scenario:
            raise DecodeError("missing field", "start needs the scenario")
        return req


@dataclass(frozen=True)
class HostReply(_Map):
    ok: bool
    version: str
    host: str
    error: str = ""
    time_unix: float = 0.0  # the host's clock when it answered
    hostname: str = ""
    cores: int = 0
    free_mem_mb: int = 0
    robots: tuple[int, ...] | None = None  # the robot ids it may run; None: any
    running: int = 0
    pid: int | None = None
    processes: tuple[tuple[str, int, int | None], ...] = ()
    code: int | None = None
    log: str = ""
    stats: str = ""

    CHECKS: ClassVar[dict[str, Any]] = {
        "ok": _bool,
        "version": _text(64),
        "host": _text(64),
        "error": _text(MAX_TEXT),
        "time_unix": _float(0.0, 1e11),
        "hostname": _text(256),
        "cores": _int(0, 1 << 20),
        "free_mem_mb": _int(0, 1 << 40),
        "robots": _robots,
        "running": _int(0, 1 << 20),
        "pid": _int(0, 2**31, optional=True),
        "processes": _processes,
        "code": _int(-255, 255, optional=True),
        "log": _text(MAX_LOG_BYTES),
        "stats": _text(MAX_STATS_BYTES),
    }

    @classmethod
    def from_bytes(cls, payload: bytes) -> HostReply:
        return cls(**cls._decode(payload))


def tail_bytes(text: str, limit: int) -> str:
    """The end of ``text`` that fits in ``limit`` bytes of UTF-8, cut at a line."""
    data = text.encode()
    if len(data) <= limit:
        return text
    cut = data[-limit:].decode(errors="ignore")
    return cut.partition("\n")[2] if "\n" in cut else cut
