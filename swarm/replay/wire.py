"""Reading a run's ``wire.mcap`` (formation_swarm.runtime.wirefile writes it).

The file is read in one pass, in the order it was written, which is each
receiver's messages in the order it took them: its channels (a key and the
process that received it), its ``run`` metadata and the messages of the keys
asked for. A file whose writer was killed does
not end with the footer and MCAP's magic: it is read as far as it reads (to
its last whole chunk) and ``complete`` says it is not. A whole file that does
not read (a chunk whose checksum fails), a file that is no MCAP file, or one
without ``run`` metadata is a :class:`WireError` naming the file.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Container
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message, Metadata
from mcap.stream_reader import StreamReader
from zstandard import ZstdError

from formation_swarm.runtime.wirefile import ENCODING, METADATA, RECEIVER, ROS_ENCODING

MAGIC = b"\x89MCAP0\r\n"  # an MCAP file's first and last 8 bytes (its specification)
# What the run metadata must hold.
NEEDED = ("run_id", "seed", "dt_s", "scenario")
# What a file that is not a whole wire recording raises as it is read: the
# reader's own errors, a checksum that fails (a ValueError), a record that
# does not parse, a chunk that does not decompress (zstd; lz4: RuntimeError).
UNREADABLE = (McapError, ValueError, struct.error, UnicodeDecodeError, ZstdError, RuntimeError, MemoryError, OSError)


class WireError(ValueError):
    """A wire recording that cannot be read (one line, naming the file)."""


@dataclass(frozen=True)
class Heard:
    """One message as a process received it: its key, the wire's bytes, its sim
    time (log time, ns), when it was received (wall ns) and by whom (world,
    logger, agent-3; a restarted agent agent-3.2)."""

    key: str
    payload: bytes
    log_ns: int
    received_ns: int
    receiver: str = ""


@dataclass
class Wire:
    """What was read of a wire recording."""

    path: Path
    info: dict[str, str]  # the run metadata (runtime.wirefile.run_info)
    messages: list[Heard] = field(default_factory=list)  # of the keys asked for, each receiver's in its order
    counts: dict[str, int] = field(default_factory=dict)  # every key's messages, by key (all receivers)
    by_receiver: dict[str, dict[str, int]] = field(default_factory=dict)  # receiver -> key -> messages
    complete: bool = True  # False: no footer (its writer was killed), read to its last whole chunk

    @property
    def run_id(self) -> str:
        return self.info["run_id"]

    @property
    def seed(self) -> int:
        return int(self.info["seed"])


def read_wire(path: Path, keep: Container[str] | Callable[[str], bool] = ()) -> Wire:
    """The recording at ``path``; ``keep``: the keys whose messages are kept (a
    set, or a test of the key), the others only counted."""
    try:
        stream = path.open("rb")
    except OSError as exc:
        raise WireError(f"{path}: cannot read it: {exc.strerror or exc}") from None
    reader = _Reader(path, keep if callable(keep) else keep.__contains__)
    with stream:
        whole = _ends_whole(stream)
        try:
            for record in StreamReader(stream, validate_crcs=True).records:
                if reader.take(record):
                    break
        except WireError:
            raise
        except UNREADABLE as exc:
            if whole or not reader.wire.info:  # damaged, or not ours: nothing to go on
                raise WireError(f"{path}: not a readable MCAP file ({_why(exc)})") from None
            reader.wire.complete = False  # cut short: what was read holds
    if not reader.wire.info:
        raise WireError(f"{path}: no {METADATA!r} metadata: not a wire recording of swarm run")
    return reader.wire


class _Reader:
    """Takes a recording's records in the order written."""

    def __init__(self, path: Path, wanted: Callable[[str], bool]) -> None:
        self.path = path
        self.wanted = wanted
        self.channels: dict[int, tuple[str, str]] = {}  # id -> (key, receiver)
        self.wire = Wire(path=path, info={})

    def take(self, record: Any) -> bool:
        """True at the footer: the data has ended."""
        wire = self.wire
        if isinstance(record, Message):
            got = self.channels.get(record.channel_id)
            if got is None:
                raise WireError(f"{self.path}: a message of channel {record.channel_id}, which has no channel record")
            key, receiver = got
            wire.counts[key] = wire.counts.get(key, 0) + 1
            by_key = wire.by_receiver.setdefault(receiver, {})
            by_key[key] = by_key.get(key, 0) + 1
            if self.wanted(key):
                wire.messages.append(Heard(key, record.data, record.log_time, record.publish_time, receiver))
        elif isinstance(record, Channel):
            self.channels[record.id] = _channel(self.path, record)
        elif isinstance(record, Metadata) and record.name == METADATA and not wire.info:
            wire.info = _info(self.path, record.metadata)
        return isinstance(record, Footer)


def _ends_whole(stream: Any) -> bool:
    """Whether the file ends as a finished MCAP file does (its magic after the footer)."""
    size = stream.seek(0, 2)
    if size < 2 * len(MAGIC):
        stream.seek(0)
        return False
    stream.seek(size - len(MAGIC))
    tail = stream.read(len(MAGIC))
    stream.seek(0)
    return bool(tail == MAGIC)


def _channel(path: Path, ch: Channel) -> tuple[str, str]:
    if ch.message_encoding not in (ENCODING, ROS_ENCODING):
        raise WireError(f"{path}: channel {ch.topic!r} is {ch.message_encoding!r}, expected {ENCODING!r}")
    return ch.topic, str(ch.metadata.get(RECEIVER, ""))


def _info(path: Path, data: dict[str, str]) -> dict[str, str]:
    missing = [k for k in NEEDED if k not in data]
    if missing:
        raise WireError(f"{path}: its {METADATA!r} metadata lacks {', '.join(missing)}")
    for name, read in (("seed", int), ("dt_s", float)):
        try:
            read(data[name])
        except ValueError:
            raise WireError(f"{path}: its {METADATA!r} metadata has {name} = {data[name][:40]!r}") from None
    return dict(data)


def _why(exc: Any) -> str:
    text = " ".join(str(exc).split())[:120]
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
