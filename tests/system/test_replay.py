"""``swarm replay RUN --robot N`` on runs recorded with ``--record-wire``.

Every robot of a lockstep fig11 run with an observation drop, and of a
real-time one with a drop and a freeze (the frozen robot skips observations
at its thaw), replays identical; a law changed at one step is caught at that
step's tick; bad input is one line, exit 2, nothing written; a run whose
spools were not merged (its launcher killed) is merged first."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from formation_swarm.launch.launcher import Launch
from formation_swarm.launch.result import RunResult
from formation_swarm.replay.cli import main, prepare
from formation_swarm.replay.compare import Comparison, compare
from formation_swarm.replay.feed import replay
from formation_swarm.replay.wire import read_wire
from formation_swarm.runtime.spool import SpoolWriter, path_for

pytestmark = pytest.mark.slow

PLANTED = "tests.helpers.replay_laws:Planted"


def _run(out: Path, **kwargs: object) -> RunResult:
    with Launch("fig11_obstacles", out=out, record_wire=True, progress=lambda _l: None, **kwargs) as launch:
        res = launch.wait(timeout_s=240)
    assert res.exit_code == 0
    return res


@pytest.fixture(scope="module")
def lockstep(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    out = tmp_path_factory.mktemp("replay") / "lockstep"
    return _run(out, overrides={"run.duration_s": 6.0}, faults=["drop obs:3@1s for=2s p=0.5"])


@pytest.fixture(scope="module")
def realtime(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    out = tmp_path_factory.mktemp("replay") / "realtime"
    faults = ["drop obs:2@1s for=2s p=0.5", "freeze agent-3@3s for=1s"]
    return _run(out, mode="realtime", overrides={"run.duration_s": 8.0}, faults=faults)


def _replay(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    got = capsys.readouterr()
    return code, got.out, got.err


def _compared(run_dir: Path, rid: int, *sets: str) -> Comparison:
    """The record behind swarm replay's lines."""
    job = prepare(run_dir, rid, list(sets))
    return compare(job.inputs.recorded, replay(job.sc, job.seed, job.wire.run_id, job.inputs).commands)


def test_every_robot_of_a_lockstep_run_replays_identical(
    lockstep: RunResult, capsys: pytest.CaptureFixture[str]
) -> None:
    for rid in (1, 2, 3):
        got = _compared(lockstep.run_dir, rid)
        assert (got.ticks, got.differing, got.max_mps) == (120, 0, 0.0)
        code, out, err = _replay(capsys, str(lockstep.run_dir), "--robot", str(rid))
        assert (code, out.count("\n"), err) == (0, 1, "")
        assert out.startswith(f"robot {rid}: identical over 120 ticks")
    assert not (lockstep.run_dir / "replay").exists()  # no figure for an identical replay


def test_every_robot_of_a_real_time_run_replays_identical(
    realtime: RunResult, capsys: pytest.CaptureFixture[str]
) -> None:
    parts = realtime.summary["parts"]
    assert parts["agent-3"]["superseded"] > 0  # at its thaw it found several observations and answered the newest
    for rid in (1, 2, 3):
        got = _compared(realtime.run_dir, rid)
        assert (got.ticks, got.differing) == (parts[f"agent-{rid}"]["answered"], 0)
        assert _replay(capsys, str(realtime.run_dir), "--robot", str(rid))[0] == 0


def test_a_law_changed_at_one_step_differs_from_that_tick(
    lockstep: RunResult, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    law = f"controller.law={PLANTED}"
    got = _compared(lockstep.run_dir, 2, law, "controller.params.at_step=40")
    first = got.first
    assert first is not None
    assert first.replayed is not None
    assert (first.tick, got.max_tick) == (40, 40)
    assert first.replayed.left_mps == first.recorded.left_mps + 0.001
    assert first.replayed.right_mps == first.recorded.right_mps
    fig = tmp_path / "planted.png"
    argv = [str(lockstep.run_dir), "--robot", "2", "--set", law]
    code, out, _err = _replay(capsys, *argv, "--set", "controller.params.at_step=40", "--out", str(fig))
    assert code == 1
    assert out.startswith("robot 2: differs at tick 40 (t = 2.00 s)")
    assert out.endswith(f"figure: {fig}\n")
    assert fig.stat().st_size > 10_000
    # The law unchanged (its step never reached): identical, and as a what-if it draws both series.
    assert _compared(lockstep.run_dir, 2, law, "controller.params.at_step=100000").identical
    code, out, _ = _replay(capsys, *argv, "--set", "controller.params.at_step=100000")
    assert code == 0
    (drawn,) = re.findall(r"figure: (.+)", out)
    assert Path(drawn).is_file()
    assert Path(drawn) != fig  # each what-if its own file
    assert Path(drawn).name.startswith("robot-2-whatif-controller.law=tests.helpers.replay_laws")


def test_bad_input_is_one_line_exit_2_and_nothing_written(
    lockstep: RunResult, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    bad = tmp_path / "bad"
    shutil.copytree(lockstep.run_dir, bad, ignore=shutil.ignore_patterns("replay"))
    data = bytearray((bad / "wire.mcap").read_bytes())
    middle = len(data) // 2
    data[middle : middle + 16] = bytes(16)
    (bad / "wire.mcap").write_bytes(bytes(data))
    empty = tmp_path / "empty"
    empty.mkdir()
    run = str(lockstep.run_dir)
    cases = [
        ([str(tmp_path / "absent"), "--robot", "2"], f"no run folder at {tmp_path / 'absent'}"),
        ([str(empty), "--robot", "2"], f"{empty} has no wire.mcap: record the run with swarm run --record-wire"),
        ([run, "--robot", "7"], "robot 7 is not in run"),
        ([str(bad), "--robot", "2"], "not a readable MCAP file"),
        ([run, "--robot", "2", "--set", "controller.lw=lpsi"], "controller.lw"),
        ([run, "--robot", "2", "--set", "controller.law=lpsi", "--out", "x.svg"], "the figure is a PNG"),
    ]
    for argv, said in cases:
        code, out, err = _replay(capsys, *argv)
        assert (code, out) == (2, "")
        assert err.startswith("swarm replay: ")
        assert said in err
        assert err.count("\n") == 1
    assert not (bad / "replay").exists()
    assert not (lockstep.run_dir / "replay" / "robot-7.png").exists()


def test_a_run_whose_launcher_did_not_merge_is_merged_first(
    lockstep: RunResult, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A launcher killed before its end leaves the receivers' spools: swarm replay merges them, and says so."""
    cut = tmp_path / "cut"
    shutil.copytree(lockstep.run_dir, cut, ignore=shutil.ignore_patterns("replay", "wire.mcap"))
    wire = read_wire(lockstep.run_dir / "wire.mcap", keep=lambda key: True)
    spools: dict[str, SpoolWriter] = {}
    for h in wire.messages:  # each receiver's messages, as its process spooled them
        if h.receiver not in spools:
            spools[h.receiver] = SpoolWriter(path_for(cut, h.receiver), wire.run_id, h.receiver)
        spools[h.receiver].add(h.key, h.payload, tick=h.log_ns // 50_000_000, received_ns=h.received_ns)
    for s in spools.values():
        s.close()
    code, out, err = _replay(capsys, str(cut), "--robot", "3")
    assert (code, err) == (0, f"{cut}: its wire spools merged into wire.mcap (its launcher did not finish)\n")
    assert out.startswith("robot 3: identical over 120 ticks")
    assert not (cut / "wire").exists()
    assert read_wire(cut / "wire.mcap").by_receiver == wire.by_receiver
