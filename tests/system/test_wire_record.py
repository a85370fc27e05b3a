"""``swarm run --record-wire``: every message each process received, spooled
by its receiver and merged into wire.mcap at the run's end.

A lockstep fig11 run with an observation drop fault: its file reads back
with mcap's own reader, and each (key, receiver) channel's message count is
what the run's links counted as received at that receiver (drops are the
receiver link layer's: the spool keeps what arrived, the replay drops it
again). A run stopped by a signal is merged; an agent killed and restarted
leaves its spool readable to its last flush, and its successor spools as
agent-N.2."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from formation_swarm.launch.launcher import Launch
from formation_swarm.launch.result import RunResult
from formation_swarm.protocol.keys import Keys
from formation_swarm.replay.wire import read_wire

pytestmark = pytest.mark.slow

DROP = "drop obs:3@1s for=2s p=0.5"
SHORT = {"run.duration_s": 6.0}  # 120 ticks


@pytest.fixture(scope="module")
def lockstep(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    out = tmp_path_factory.mktemp("wire") / "run"
    with Launch(
        "fig11_obstacles", out=out, record_wire=True, overrides=SHORT, faults=[DROP], progress=lambda _l: None
    ) as launch:
        res = launch.wait(timeout_s=240)
    assert res.exit_code == 0
    return res


def _mcap_counts(path: Path) -> tuple[dict[tuple[str, str], int], Any]:
    """Messages per (topic, receiver) by mcap's own reader, and its summary."""
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        counts: dict[tuple[str, str], int] = {}
        for _schema, channel, _message in reader.iter_messages(log_time_order=False):
            at = (channel.topic, channel.metadata["receiver"])
            counts[at] = counts.get(at, 0) + 1
    return counts, summary


def test_each_channels_messages_are_what_its_receivers_links_received(lockstep: RunResult) -> None:
    s = lockstep.summary
    k = Keys(s["run_id"])
    counts, summary = _mcap_counts(lockstep.run_dir / "wire.mcap")
    assert summary is not None  # the footer and its summary: a whole file
    assert summary.statistics.message_count == sum(counts.values())
    assert not (lockstep.run_dir / "wire").exists()  # the spools, merged, are gone
    links = s["links"]
    assert links["obs:0>3"]["dropped"] > 0  # the fault dropped some, at robot 3's end of the link
    for rid in (1, 2, 3):
        assert counts[(k.obs(rid), f"agent-{rid}")] == links[f"obs:0>{rid}"]["received"] == 120
        assert counts[(k.cmd(rid), "world")] == links[f"cmd:{rid}>0"]["received"] == 120
    for rid in (2, 3):
        assert counts[(k.codes, f"agent-{rid}")] == links[f"formation:1>{rid}"]["received"] > 0
    assert counts[(k.truth, "logger")] >= 1  # batches: one put carries many ticks
    assert counts[(k.codes, "logger")] == links["formation:1>2"]["received"]
    # Nothing but what each process subscribes to: the logger no longer hears observations or commands.
    assert {r for (_key, r) in counts} == {"world", "logger", "agent-1", "agent-2", "agent-3"}
    assert not [key for (key, r) in counts if r == "logger" and key.endswith(("/obs", "/cmd"))]


def test_its_metadata_and_times_are_the_runs(lockstep: RunResult) -> None:
    wire = read_wire(lockstep.run_dir / "wire.mcap", keep=lambda key: key.endswith("/robot/2/obs"))
    s = lockstep.summary
    assert (wire.run_id, wire.seed, wire.complete) == (s["run_id"], s["seed"], True)
    as_run = tomllib.loads((lockstep.run_dir / "scenario.toml").read_text())
    assert tomllib.loads(wire.info["scenario"]) == as_run
    assert set(wire.info) >= {"formation_swarm", "zenoh", "python", "dt_s"}
    # Log time is the sim time, tick * dt; publish time the wall time it was received, in order.
    assert {h.receiver for h in wire.messages} == {"agent-2"}
    assert [h.log_ns for h in wire.messages] == [k * 50_000_000 for k in range(120)]
    heard = [h.received_ns for h in wire.messages]
    assert heard == sorted(heard)
    assert 0 < heard[-1] - heard[0] < 60e9


def test_a_run_stopped_by_a_signal_is_merged(tmp_path: Path) -> None:
    out = tmp_path / "run"
    over = {"run.duration_s": 60.0}
    with Launch(
        "fig11_obstacles", out=out, mode="realtime", record_wire=True, overrides=over, progress=lambda _l: None
    ) as launch:
        spool = out / "wire" / "agent-2.spool"
        assert launch.wait_until(lambda: spool.exists() and spool.stat().st_size > 20_000, timeout_s=60)
        launch.interrupt()  # as a Ctrl-C: every process gets its stop signal
        res = launch.wait(timeout_s=60)
    assert res.exit_code == 130
    got = read_wire(out / "wire.mcap", keep=lambda key: True)
    assert got.complete
    assert not (out / "wire").exists()
    assert got.by_receiver["agent-2"][Keys(res.summary["run_id"]).obs(2)] > 20


def test_a_killed_agents_spool_reads_to_its_last_flush(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with Launch(
        "fig11_obstacles",
        out=out,
        mode="realtime",
        record_wire=True,
        overrides={"run.duration_s": 6.0},
        faults=["restart agent-3@3s after=1s"],
        progress=lambda _l: None,
    ) as launch:
        launch.wait(timeout_s=120)
    k = Keys(launch.run_id)
    got = read_wire(out / "wire.mcap", keep={k.obs(3)})
    first = [h.log_ns // 50_000_000 for h in got.messages if h.receiver == "agent-3"]
    # Flushed every 0.5 s: at most that much before the kill at tick 60 is lost, and nothing after it.
    assert first == list(range(len(first)))
    assert 40 <= len(first) <= 61
    second = [h.log_ns // 50_000_000 for h in got.messages if h.receiver == "agent-3.2"]
    assert second  # the fresh agent's own spool, from its start on
    assert second[0] >= 70
    assert second[-1] == 119
