"""A receiver's spool (runtime.spool): what it appends reads back as appended,
a record cut by a kill is ignored (not an error), a write that fails is said
once; and its cost per message. No process is started here."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from formation_swarm.runtime.spool import RECORD, SpoolError, SpoolWriter, path_for, read_spool


def payload(i: int) -> bytes:
    return bytes([i % 256]) * (50 + i)


def test_what_is_appended_reads_back_in_order_with_what_was_decoded(tmp_path: Path) -> None:
    path = path_for(tmp_path, "agent-3.2")
    assert path == tmp_path / "wire" / "agent-3.2.spool"
    w = SpoolWriter(path, "run-a", "agent-3.2")
    w.add("swarm/run-a/robot/3/obs", payload(1), tick=7, seq=8, received_ns=1_000)
    w.add("swarm/run-a/robot/*/formation", payload(2), received_ns=2_000)  # not decoded: no tick, no seq
    w.add("swarm/run-a/robot/3/obs", b"", tick=0, seq=0, received_ns=3_000)
    w.close()
    got = read_spool(path)
    assert (got.run_id, got.process, got.whole) == ("run-a", "agent-3.2", True)
    assert [(r.key.rsplit("/", 1)[1], r.payload, r.received_ns, r.tick, r.seq) for r in got.records] == [
        ("obs", payload(1), 1_000, 7, 8),
        ("formation", payload(2), 2_000, None, None),
        ("obs", b"", 3_000, 0, 0),
    ]
    assert w.stats() == {"file": "agent-3.2.spool", "messages": 3}


def test_a_record_cut_by_a_kill_is_ignored_and_what_was_flushed_reads(tmp_path: Path) -> None:
    path = tmp_path / "world.spool"
    w = SpoolWriter(path, "r", "world")
    for i in range(10):
        w.add("k", payload(i), tick=i)
    w.flush()  # what a kill leaves: up to the last flush
    for i in range(10, 15):
        w.add("k", payload(i), tick=i)  # still buffered
    flushed = path.read_bytes()
    assert [r.tick for r in read_spool(path).records] == list(range(10))
    w.close()
    data = path.read_bytes()
    assert len(data) > len(flushed)
    # Cut anywhere in the last record (its header or its bytes): the records before it read, no error.
    last = RECORD.size + 1 + len(payload(14))
    for cut in (1, RECORD.size - 1, RECORD.size + 1, last - 1):
        path.write_bytes(data[: len(data) - cut])
        got = read_spool(path)
        assert [r.tick for r in got.records] == list(range(14))
        assert not got.whole
    path.write_bytes(data[: len(flushed)])
    assert read_spool(path).whole


def test_files_that_are_no_spool_are_one_line(tmp_path: Path) -> None:
    junk = tmp_path / "junk.spool"
    junk.write_bytes(b"not a spool at all")
    for path, said in ((junk, "not a wire spool"), (tmp_path / "absent.spool", "cannot read it")):
        with pytest.raises(SpoolError) as err:
            read_spool(path)
        assert said in str(err.value)
        assert str(path) in str(err.value)


class FullDisk:
    def write(self, _data: bytes) -> int:
        raise OSError(28, "No space left on device")

    def close(self) -> None:
        pass


def test_a_write_that_fails_is_said_once_and_ends_the_spool(tmp_path: Path) -> None:
    said: list[str] = []
    w = SpoolWriter(tmp_path / "world.spool", "r", "world", said.append)
    w.file = FullDisk()  # type: ignore[assignment]  # the disk fills mid-run
    w.add("k", b"x")
    w.flush()
    w.add("k", b"y")
    w.close()
    assert w.file is None
    assert len(said) == 1
    assert "cannot write the wire spool" in said[0]
    assert "No space left on device; recording no more of it" in said[0]
    assert read_spool(w.path).records == []  # its header, written at the start


def test_an_append_costs_a_few_microseconds(tmp_path: Path) -> None:
    w = SpoolWriter(tmp_path / "agent-1.spool", "r", "agent-1")
    body = payload(200)  # an observation's size, about
    n = 20_000
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        for i in range(n):
            w.add("swarm/r/robot/1/obs", body, tick=i, seq=i)
        best = min(best, (time.perf_counter() - t0) / n)
    w.close()
    assert len(read_spool(w.path).records) == 3 * n
    assert best < 10e-6, f"{best * 1e6:.1f} us per message"
