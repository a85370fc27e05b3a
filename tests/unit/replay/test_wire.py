"""The wire recording, merged from the receivers' spools (runtime.wirefile)
and read back (replay.wire): what each message carries, a file cut short,
and files that are not a wire recording at all. No process is started here."""

from __future__ import annotations

import io
import shutil
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from formation_swarm.protocol.batch import pack_batch
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Command, FormationCode, Observation
from formation_swarm.replay.wire import WireError, read_wire
from formation_swarm.runtime.spool import SpoolWriter, path_for
from formation_swarm.runtime.wirefile import ENCODING, FILE_NAME, METADATA, WireWriter, merge_spools, run_info, stamp
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod

SC = scenario_mod.load("fig11_obstacles")
K = Keys("wire-test")
DT_NS = 50_000_000  # fig11's dt, 0.05 s


def obs(rid: int, tick: int) -> bytes:
    return Observation(
        sender=0, seq=tick + 1, tick=tick, time_s=tick * 0.05, pose=(0.0, 0.1 * tick, 0.0), readings=(), obstacles=()
    ).to_bytes()


def cmd(rid: int, tick: int) -> bytes:
    return Command(
        sender=rid, seq=tick + 1, tick=tick, left_mps=1.0, right_mps=1.25, formation=0, done=False
    ).to_bytes()


def recorder(path: Path) -> WireWriter:
    return WireWriter(path, SC.dt_s, run_info(K.run_id, SC))


def add(rec: WireWriter, key: str, payload: bytes, ns: int) -> None:
    """As agent-3 took it, at its own tick."""
    got = stamp(payload)
    rec.add("agent-3", key, payload, tick=0 if got is None else got[0], received_ns=ns)


def test_stamp_reads_a_messages_tick_and_seq_and_a_batchs_first() -> None:
    assert stamp(obs(2, 7)) == (7, 8)
    code = FormationCode(sender=1, seq=30, tick=12, code=1).to_bytes()
    assert stamp(code) == (12, 30)
    assert stamp(pack_batch([cmd(2, 40), cmd(2, 41)])) == (40, 41)
    assert stamp(pack_batch([])) is None  # an end-of-stream mark has no tick
    for junk in (b"", b"\x00", b"x" * 100, b"\x95\x01\x01\x00\xc0\xc0", pack_batch([b"\x01"]), b"\x91" * 70_000):
        assert stamp(junk) is None


def test_the_spools_merge_into_one_channel_per_key_and_receiver_at_their_sim_times(tmp_path: Path) -> None:
    (tmp_path / "scenario.toml").write_text(scenario_files.dumps(SC.raw))
    world = SpoolWriter(path_for(tmp_path, "world"), K.run_id, "world")
    world.add(K.cmd(2), cmd(2, 0), tick=0, received_ns=1_200)  # the world's tick when it took it
    world.add(K.cmd(2), cmd(2, 1), tick=1, received_ns=2_200)
    world.close()
    agent = SpoolWriter(path_for(tmp_path, "agent-2"), K.run_id, "agent-2")
    agent.add(K.obs(2), obs(2, 0), tick=0, seq=1, received_ns=1_000)
    agent.add(K.obs(2), obs(2, 1), tick=1, seq=2, received_ns=2_000)
    code = FormationCode(sender=1, seq=3, tick=1, code=1).to_bytes()
    agent.add(K.codes, code, tick=1, seq=3, received_ns=2_100)
    agent.close()
    logger = SpoolWriter(path_for(tmp_path, "logger"), K.run_id, "logger")
    logger.add(K.codes, code, received_ns=2_150)  # not decoded: its receiver's latest sim time, none yet
    logger.add(K.truth, pack_batch([]), received_ns=9_000)
    logger.close()
    said: list[str] = []
    merged = merge_spools(tmp_path, said.append)
    assert said == []
    assert merged is not None
    assert merged["by_receiver"] == {
        "world": {K.cmd(2): 2},
        "agent-2": {K.obs(2): 2, K.codes: 1},
        "logger": {K.codes: 1, K.truth: 1},
    }
    assert not (tmp_path / "wire").exists()  # the spools are gone once merged
    wire = read_wire(tmp_path / FILE_NAME, keep=lambda key: True)
    assert wire.complete
    assert [(h.receiver, h.key, h.received_ns, h.log_ns) for h in wire.messages] == [
        ("world", K.cmd(2), 1_200, 0),
        ("world", K.cmd(2), 2_200, DT_NS),
        ("agent-2", K.obs(2), 1_000, 0),
        ("agent-2", K.obs(2), 2_000, DT_NS),
        ("agent-2", K.codes, 2_100, DT_NS),
        ("logger", K.codes, 2_150, 0),
        ("logger", K.truth, 9_000, 0),
    ]
    assert wire.messages[4].payload == code
    assert wire.counts == {K.cmd(2): 2, K.obs(2): 2, K.codes: 2, K.truth: 1}
    assert wire.by_receiver == merged["by_receiver"]
    assert (wire.run_id, wire.seed, float(wire.info["dt_s"])) == (K.run_id, SC.seed, 0.05)
    assert scenario_mod.from_dict(__import__("tomllib").loads(wire.info["scenario"])).robots == SC.robots
    assert set(wire.info) >= {"formation_swarm", "zenoh", "python"}
    # mcap's own reader reads it too: its summary, the channels' receivers, the senders' seq.
    with (tmp_path / FILE_NAME).open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        assert summary.statistics.message_count == 7
        assert {c.message_encoding for c in summary.channels.values()} == {ENCODING}
        assert sorted((c.topic, c.metadata["receiver"]) for c in summary.channels.values()) == sorted(
            [(K.cmd(2), "world"), (K.obs(2), "agent-2"), (K.codes, "agent-2"), (K.codes, "logger"), (K.truth, "logger")]
        )
        assert [m.sequence for _s, _c, m in reader.iter_messages(log_time_order=False)] == [0, 0, 1, 2, 3, 0, 0]
    only_obs = read_wire(tmp_path / FILE_NAME, keep={K.obs(2)})
    assert [h.payload for h in only_obs.messages] == [obs(2, 0), obs(2, 1)]
    assert only_obs.counts == wire.counts  # every key is counted, kept or not
    assert merge_spools(tmp_path) is None  # nothing left to merge


def test_a_spool_that_does_not_read_is_said_and_left(tmp_path: Path) -> None:
    (tmp_path / "scenario.toml").write_text(scenario_files.dumps(SC.raw))
    good = SpoolWriter(path_for(tmp_path, "agent-1"), K.run_id, "agent-1")
    good.add(K.obs(1), obs(1, 0), tick=0, seq=1)
    good.close()
    bad = path_for(tmp_path, "agent-2")
    bad.write_bytes(b"junk")
    said: list[str] = []
    merged = merge_spools(tmp_path, said.append)
    assert merged is not None
    assert merged["by_receiver"] == {"agent-1": {K.obs(1): 1}}
    assert len(said) == 1
    assert "not a wire spool: left out of wire.mcap" in said[0]
    assert bad.exists()


def test_a_file_cut_short_reads_to_its_last_whole_chunk(tmp_path: Path) -> None:
    path, cut = tmp_path / "wire.mcap", tmp_path / "cut.mcap"
    rec = recorder(path)
    for tick in range(20):
        add(rec, K.obs(3), obs(3, tick), tick)
    rec.writer.flush()  # a chunk written out
    for tick in range(20, 30):
        add(rec, K.obs(3), obs(3, tick), tick)  # still in the chunk under way
    shutil.copy(path, cut)  # what a kill leaves on disk
    rec.close()
    wire = read_wire(cut, keep={K.obs(3)})
    assert not wire.complete
    assert [h.received_ns for h in wire.messages] == list(range(20))
    whole = read_wire(path, keep={K.obs(3)})
    assert whole.complete
    assert len(whole.messages) == 30
    # Cut anywhere: what reads is a prefix of what was written, never an error past the metadata.
    data = path.read_bytes()
    first_chunk = len(cut.read_bytes())
    for size in (first_chunk - 1, first_chunk + 7, len(data) - 40):  # the footer is the last 37 bytes
        cut.write_bytes(data[:size])
        part = read_wire(cut, keep={K.obs(3)})
        assert not part.complete
        got = [h.received_ns for h in part.messages]
        assert got == list(range(len(got)))
        assert len(got) in (0, 20, 30)
    cut.write_bytes(data[:-1])  # its footer read, its closing magic cut: every message is there
    assert read_wire(cut, keep={K.obs(3)}).complete


def test_files_that_are_no_wire_recording_are_refused_with_one_line(tmp_path: Path) -> None:
    good = tmp_path / "wire.mcap"
    rec = recorder(good)
    for tick in range(50):
        add(rec, K.obs(2), obs(2, tick), tick)
    rec.close()
    data = bytearray(good.read_bytes())
    flipped = tmp_path / "flipped.mcap"
    middle = len(data) // 2
    data[middle : middle + 8] = bytes(b ^ 0xFF for b in data[middle : middle + 8])
    flipped.write_bytes(bytes(data))
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all" * 10)
    bare = tmp_path / "bare.mcap"  # an MCAP file, but not ours: no run metadata
    with bare.open("wb") as f:
        w = Writer(f)
        w.start()
        w.finish()
    other = io.BytesIO()
    w = Writer(other)
    w.start()
    w.add_metadata(METADATA, {"run_id": "x"})
    w.finish()
    lacking = tmp_path / "lacking.mcap"
    lacking.write_bytes(other.getvalue())
    cases = {
        flipped: "not a readable MCAP file",
        junk: "not a readable MCAP file",
        bare: "no 'run' metadata",
        lacking: "metadata lacks seed, dt_s, scenario",
        tmp_path / "absent.mcap": "cannot read it",
    }
    for path, said in cases.items():
        with pytest.raises(WireError) as err:
            read_wire(path, keep={K.obs(2)})
        assert said in str(err.value)
        assert str(path) in str(err.value)
        assert "\n" not in str(err.value)
