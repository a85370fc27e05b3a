"""A receiver's spool: every run message a process took, appended to a file
of its own in the run folder (``wire/<process>.spool``), for the run's wire
recording (formation_swarm.runtime.wirefile merges the spools into
``wire.mcap`` when the run ends).

Recording where the message is received costs no Zenoh traffic: each
process already holds the bytes it was handed. A record is a fixed header
(``RECORD``: the key's and the payload's lengths, the wall time received in
ns, the sim tick and the sender's seq when the receiver had decoded them,
else -1) followed by the key and the payload. The file starts with
``MAGIC`` and one header record holding the run id and the process name
(JSON). Records are buffered and written out every ``FLUSH_PERIOD_NS`` of
wall time and at close, so a process killed mid-run leaves its spool
readable up to its last flush; :func:`read_spool` reads to the last whole
record and ignores a cut one.

Not thread-safe: each receiver appends from the one thread that takes its
messages (the agent's loop, the world's loop, the logger's loop).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import struct
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

MAGIC = b"SWSPOOL1"
SUFFIX = ".spool"
FOLDER = "wire"  # the spools' folder in a run folder
RECORD = struct.Struct("<HIqqq")  # key length, payload length, received ns, tick (-1: none), seq (-1: none)
FLUSH_PERIOD_NS = 500_000_000
# A record beyond these is not ours: the reader stops there (a file damaged or not a spool).
MAX_KEY_BYTES = 1024
MAX_PAYLOAD_BYTES = 16 * 1024 * 1024


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument(
        "--wire-spool",
        metavar="FILE",
        help="append every run message this process receives to FILE, for the run's wire recording "
        f"(swarm run puts it in the run folder's {FOLDER}/ and merges the spools into wire.mcap)",
    )


def open_spool(args: argparse.Namespace, complain: Callable[[str], None]) -> SpoolWriter | None:
    """The spool ``--wire-spool`` asks for (None: none), named for its process by
    its file name (agent-3.2.spool: agent-3.2); OSError if it cannot be made."""
    if getattr(args, "wire_spool", None) is None:
        return None
    path = Path(args.wire_spool)
    return SpoolWriter(path, args.run, path.name.removesuffix(SUFFIX), complain)


def open_path(path: str | None, run_id: str, complain: Callable[[str], None]) -> SpoolWriter | None:
    """As :func:`open_spool`, but a spool that cannot be made is said and left out (None): the process goes on."""
    if path is None:
        return None
    try:
        return SpoolWriter(Path(path), run_id, Path(path).name.removesuffix(SUFFIX), complain)
    except OSError as exc:
        complain(f"cannot spool the wire to {path}: {exc}; not recording what this process receives")
        return None


def path_for(run_dir: Path, process: str) -> Path:
    """Where ``process`` (world, logger, agent-3, agent-3.2) spools in ``run_dir``."""
    return run_dir / FOLDER / f"{process}{SUFFIX}"


class SpoolWriter:
    """Appends what one process received (see the module's docstring). A write
    that fails (a full disk) is said once through ``complain`` and ends the
    spool; the process goes on."""

    def __init__(self, path: Path, run_id: str, process: str, complain: Callable[[str], None] = print) -> None:
        self.path = path
        self.complain = complain
        path.parent.mkdir(parents=True, exist_ok=True)
        self.file: IO[bytes] | None = path.open("wb", buffering=0)
        head = json.dumps({"run_id": run_id, "process": process}).encode()
        self.file.write(MAGIC + struct.pack("<I", len(head)) + head)  # a spool that reads from the start
        self.buf = bytearray()
        self.keys: dict[str, bytes] = {}  # each key encoded once
        self.messages = 0
        self.next_flush_ns = time.time_ns() + FLUSH_PERIOD_NS

    def add(
        self, key: str, payload: bytes, tick: int | None = None, seq: int | None = None, received_ns: int = 0
    ) -> None:
        """One message received at ``received_ns`` (wall ns; 0: now); ``tick``/``seq``:
        what the receiver decoded, if it did."""
        if self.file is None:
            return
        kb = self.keys.get(key)
        if kb is None:
            kb = self.keys[key] = key.encode()[:MAX_KEY_BYTES]
        now = received_ns or time.time_ns()
        buf = self.buf
        buf += RECORD.pack(len(kb), len(payload), now, -1 if tick is None else tick, -1 if seq is None else seq)
        buf += kb
        buf += payload
        self.messages += 1
        if now >= self.next_flush_ns:
            self.flush(now)

    def flush(self, now_ns: int | None = None) -> None:
        """Write out what is buffered: a kill loses no more than what came after."""
        self.next_flush_ns = (time.time_ns() if now_ns is None else now_ns) + FLUSH_PERIOD_NS
        if self.file is None or not self.buf:
            return
        try:
            self.file.write(self.buf)
        except OSError as exc:
            self.complain(f"cannot write the wire spool {self.path}: {exc}; recording no more of it")
            with contextlib.suppress(OSError):
                self.file.close()
            self.file = None
        self.buf.clear()

    def close(self) -> None:
        if self.file is not None:
            self.flush()
            if self.file is not None:
                self.file.close()
                self.file = None

    def stats(self) -> dict[str, Any]:
        return {"file": self.path.name, "messages": self.messages}


@dataclass(frozen=True)
class Record:
    """One message as its receiver took it."""

    key: str
    payload: bytes
    received_ns: int
    tick: int | None
    seq: int | None


@dataclass
class Spool:
    """What was read of a spool: its header and whether it ended on a whole record."""

    path: Path
    run_id: str
    process: str
    records: list[Record]
    whole: bool = True  # False: it ends in a cut record (its process was killed between writes)


class SpoolError(ValueError):
    """A file that is not a spool (one line, naming it)."""


def read_spool(path: Path) -> Spool:
    """The spool at ``path``, read to its last whole record."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SpoolError(f"{path}: cannot read it: {exc.strerror or exc}") from None
    if not data.startswith(MAGIC) or len(data) < len(MAGIC) + 4:
        raise SpoolError(f"{path}: not a wire spool")
    pos = len(MAGIC)
    (n,) = struct.unpack_from("<I", data, pos)
    pos += 4
    try:
        head = json.loads(data[pos : pos + n])
        run_id, process = str(head["run_id"]), str(head["process"])
    except (ValueError, KeyError, TypeError):
        raise SpoolError(f"{path}: its header does not read") from None
    pos += n
    records = list(_records(data, pos))
    whole = sum(RECORD.size + len(r.key.encode()) + len(r.payload) for r in records) == len(data) - pos
    return Spool(path, run_id, process, records, whole)


def _records(data: bytes, pos: int) -> Iterator[Record]:
    size, end = RECORD.size, len(data)
    while pos + size <= end:
        nk, np_, ns, tick, seq = RECORD.unpack_from(data, pos)
        stop = pos + size + nk + np_
        if nk > MAX_KEY_BYTES or np_ > MAX_PAYLOAD_BYTES or stop > end:
            return  # cut short by a kill, or not ours past here
        k0 = pos + size
        try:
            key = data[k0 : k0 + nk].decode()
        except UnicodeDecodeError:
            return
        yield Record(key, data[k0 + nk : stop], ns, None if tick < 0 else tick, None if seq < 0 else seq)
        pos = stop
