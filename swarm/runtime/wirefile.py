"""The run's wire recording, ``wire.mcap``: every message each receiver took,
merged from the receivers' spools (formation_swarm.runtime.spool) when the
run ends.

One channel per (key, receiver): its topic is the concrete key the message
was put on, its metadata ``{"receiver": PROCESS}`` names the process that
took it (world, logger, agent-3; a restarted agent is agent-3.2); message
encoding ``msgpack`` (the wire's own bytes, batches as batches), or ``cdr``
for a ROS 2 sample the bridge took (a key outside ``swarm/``). Log time is
the message's sim time (its tick times dt, in ns, as its receiver decoded
it); a message its receiver did not decode (a batch, a command the world
decodes later) gets the receiver's latest sim time. Publish time is the wall
time it was received (ns since the epoch); a message's sequence field is its
sender's seq when the receiver decoded it (modulo 2**32), else 0. One
metadata record, ``run``, holds the run id, seed, dt, the scenario as run
(TOML) and the versions. Messages are written spool by spool, each in the
order its receiver took them.
"""

from __future__ import annotations

import contextlib
import platform
import warnings
from collections.abc import Callable
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import IO, Any

import msgpack
from mcap.writer import CompressionType, Writer

from formation_swarm.common.version import __version__
from formation_swarm.protocol.codec import BATCH_TAG, MAX_PAYLOAD_BYTES, MAX_TICK
from formation_swarm.protocol.keys import ROOT
from formation_swarm.runtime import spool as spool_mod
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.files import dumps

FILE_NAME = "wire.mcap"
ENCODING = "msgpack"
ROS_ENCODING = "cdr"  # the ROS 2 bridge's cmd_vel samples, on rmw_zenoh's keys
_U64_MAX = 2**64 - 1
METADATA = "run"  # the name of the metadata record
RECEIVER = "receiver"  # the channel metadata naming the process that took its messages
PROFILE = ""  # no MCAP profile: our own messages, not ROS's
CHUNK_BYTES = 1024 * 1024


def versions() -> dict[str, str]:
    try:
        zenoh_version = importlib_metadata.version("eclipse-zenoh")
    except importlib_metadata.PackageNotFoundError:
        zenoh_version = "unknown"
    return {"formation_swarm": __version__, "zenoh": zenoh_version, "python": platform.python_version()}


def stamp(payload: bytes) -> tuple[int, int] | None:
    """(tick, seq) of an encoded message, or of a batch's first message; None
    when the payload has none (an empty batch, not one of ours). Reads the
    header only, never the fields, and never raises."""
    try:
        if len(payload) > MAX_PAYLOAD_BYTES:
            return None
        unpacker = msgpack.Unpacker(raw=True, max_buffer_size=MAX_PAYLOAD_BYTES)
        unpacker.feed(payload)
        n = unpacker.read_array_header()
        tag = unpacker.unpack()
        if tag == BATCH_TAG and n == 3:
            unpacker.skip()  # the version
            if unpacker.read_array_header() == 0:
                return None
            first = unpacker.unpack()
            return stamp(first) if isinstance(first, bytes) else None
        if n < 5:
            return None
        unpacker.skip()  # the version
        unpacker.skip()  # the sender
        seq, tick = unpacker.unpack(), unpacker.unpack()
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError, msgpack.OutOfData):
        return None
    ok = all(type(v) is int and 0 <= v <= MAX_TICK for v in (seq, tick))
    return (tick, seq) if ok else None


def run_info(run_id: str, sc: scenario_mod.Scenario) -> dict[str, str]:
    """The metadata record: what a replay needs to rebuild the run's roles."""
    return {"run_id": run_id, "seed": str(sc.seed), "dt_s": repr(sc.dt_s), "scenario": dumps(sc.raw), **versions()}


class WireWriter:
    """Writes ``wire.mcap`` (see the module's docstring); ``close`` writes its summary and footer."""

    def __init__(self, path: Path, dt_s: float, info: dict[str, str]) -> None:
        self.path = path
        self.dt_ns = dt_s * 1e9
        self.file: IO[bytes] = path.open("wb")
        self.writer = Writer(self.file, chunk_size=CHUNK_BYTES, compression=CompressionType.ZSTD)
        self.writer.start(profile=PROFILE, library=f"formation_swarm {__version__}")
        self.writer.add_metadata(METADATA, info)
        self.channels: dict[tuple[str, str], int] = {}
        self.counts: dict[str, dict[str, int]] = {}  # receiver -> key -> messages

    def add(self, receiver: str, key: str, payload: bytes, *, tick: int, received_ns: int, seq: int = 0) -> None:
        ch = self.channels.get((key, receiver))
        if ch is None:
            ch = self.channels[(key, receiver)] = self.writer.register_channel(
                topic=key,
                message_encoding=ENCODING if key.startswith(f"{ROOT}/") else ROS_ENCODING,
                schema_id=0,
                metadata={RECEIVER: receiver},
            )
        # A forged tick (up to 2^53) would overflow MCAP's u64 nanoseconds: it is kept, at the end of time.
        log_ns = min(round(tick * self.dt_ns), _U64_MAX)
        self.writer.add_message(
            ch, log_time=log_ns, data=payload, publish_time=min(received_ns, _U64_MAX), sequence=seq & 0xFFFFFFFF
        )
        by_key = self.counts.setdefault(receiver, {})
        by_key[key] = by_key.get(key, 0) + 1

    def add_spool(self, spool: spool_mod.Spool) -> None:
        last_tick = 0  # the receiver's latest sim time, for a message it did not decode
        for r in spool.records:
            if r.tick is not None:
                last_tick = max(last_tick, r.tick)
            tick = last_tick if r.tick is None else r.tick
            self.add(spool.process, r.key, r.payload, tick=tick, received_ns=r.received_ns, seq=r.seq or 0)

    def close(self) -> None:
        try:
            self.writer.finish()
        finally:
            self.file.close()


def spools_of(run_dir: Path) -> list[Path]:
    """The spools waiting in ``run_dir`` (none: nothing to merge)."""
    folder = run_dir / spool_mod.FOLDER
    return sorted(folder.glob(f"*{spool_mod.SUFFIX}")) if folder.is_dir() else []


def merge_spools(run_dir: Path, say: Callable[[str], None] = print) -> dict[str, Any] | None:
    """The spools of ``run_dir`` merged into its ``wire.mcap``, then deleted;
    the counts by receiver and key (None: no spool read). A spool that is not
    one is said and left in place; the run's metadata is its scenario.toml
    and the spools' run id. One spool is in memory at a time. OSError if
    wire.mcap cannot be written."""
    paths = sorted(spools_of(run_dir), key=lambda p: _order(p.name.removesuffix(spool_mod.SUFFIX)))
    if not paths:
        return None
    with warnings.catch_warnings():  # said when the run started
        warnings.simplefilter("ignore")
        sc = scenario_mod.load(str(run_dir / "scenario.toml"))
    part = run_dir / f"{FILE_NAME}.part"  # renamed once whole: a wire.mcap is never a merge cut short
    writer: WireWriter | None = None
    merged: list[Path] = []
    cut: list[str] = []
    try:
        for p in paths:
            try:
                spool = spool_mod.read_spool(p)
            except spool_mod.SpoolError as exc:
                say(f"[swarm] {exc}: left out of {FILE_NAME}")
                continue
            if writer is None:
                writer = WireWriter(part, sc.dt_s, run_info(spool.run_id, sc))
            writer.add_spool(spool)
            merged.append(p)
            if not spool.whole:
                cut.append(spool.process)
    finally:
        if writer is not None:
            writer.close()
    if writer is None:
        return None
    part.replace(run_dir / FILE_NAME)
    for p in merged:
        p.unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        (run_dir / spool_mod.FOLDER).rmdir()  # empty unless a spool did not read
    return {"file": FILE_NAME, "by_receiver": writer.counts, "cut_short": cut}


def _order(name: str) -> tuple[int, str]:
    """The world first, then the agents by robot and restart, then the rest."""
    if name == "world":
        return (0, "")
    if name.startswith("agent-"):
        rid, _, nth = name.removeprefix("agent-").partition(".")
        if rid.isdigit() and (not nth or nth.isdigit()):
            return (1, f"{int(rid):09d}.{int(nth or 1):09d}")
    return (2, name)
