"""The claims' and the sensitivity's sweeps stepped in one process
(studies.engine_sweep): a sweep's rows, kept and reused, with the EKF's
errors only where a lockstep run would have a logger."""

from __future__ import annotations

import json

import pytest

from formation_swarm.studies.engine_sweep import EngineSweep, row_of, run_all
from formation_swarm.studies.jobs import Job
from tests.helpers import SCENARIOS

SHORT = {"run.duration_s": 2.0}  # 40 ticks: enough for a row
pytestmark = pytest.mark.slow  # a pool of processes, each loading the scenario: seconds


def _sweep(out, logger: bool, faults: tuple[str, ...] = ()) -> EngineSweep:
    jobs = [Job("short", SHORT, s) for s in (0, 1)]
    return EngineSweep(
        SCENARIOS / "fig9_ekf_noise.toml",
        jobs,
        out,
        workers=1,
        logger=logger,
        faults=list(faults),
        progress=lambda _l: None,
    )


def test_rows_are_kept_per_run_and_reused(tmp_path) -> None:
    with_logger = _sweep(tmp_path / "ekf", logger=True)
    without = _sweep(tmp_path / "plain", logger=False)
    rows = run_all({"ekf": with_logger, "plain": without})
    assert [r["seed"] for r in rows["ekf"]] == [0, 1]
    first = rows["ekf"][0]
    assert first["ticks"] == 40
    assert first["exit_code"] == 0
    assert first["lockstep_misses"] == 0
    assert first["combination"] == "short"
    assert first["run"] == with_logger.jobs[0].name
    assert len(first["trajectory_digest"]) == 64
    assert first["r2_ekf_rms_m"] > 0  # the logger's figures: only where the lockstep run has a logger
    assert "r2_ekf_rms_m" not in rows["plain"][0]
    # The same seed, same scenario: the same trajectory with the logger or without.
    assert rows["plain"][0]["trajectory_digest"] == first["trajectory_digest"]
    assert rows["ekf"][1]["trajectory_digest"] != first["trajectory_digest"]
    kept = tmp_path / "ekf" / "runs" / f"{with_logger.jobs[0].name}.json"
    assert json.loads(kept.read_text()) == first
    assert (tmp_path / "ekf" / "runs.csv").read_text().count("\n") == 3
    # A kept row is read back, not run again: a planted figure comes back as it is.
    kept.write_text(json.dumps({**first, "r2_rms_m": 123.0}))
    assert with_logger.run()[0]["r2_rms_m"] == 123.0


def test_a_fault_is_run_and_changes_the_run(tmp_path) -> None:
    biased = _sweep(tmp_path / "bias", logger=False, faults=("wheel_bias *@0s left=0.03",))
    task = biased.task(biased.jobs[0])
    assert task[3] == ["wheel_bias *@0s left=0.03"]
    plain = _sweep(tmp_path / "plain", logger=False)
    assert row_of(task)["trajectory_digest"] != row_of(plain.task(plain.jobs[0]))["trajectory_digest"]
