"""A run folder written here, without a run: summary.json, the shipped
fig7 scenario as run and a small recording of what swarm report, compare
and export read (a leader R1, a follower R2), in a fraction of a second."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from formation_swarm.spec.files import shipped

DT_S = 0.05
SCENARIO = "fig7_turn_vn_dynamic"


def summary_of(run_id: str, ticks: int, **more: Any) -> dict[str, Any]:
    """A summary of the fields the report reads, as a lockstep run writes them."""
    return {
        "run_id": run_id,
        "scenario": "turn-vn-dynamic",
        "seed": 1,
        "mode": "lockstep",
        "ticks": ticks,
        "sim_time_s": ticks * DT_S,
        "exit_code": 0,
        "end_reason": "duration_reached",
        "ended_at_s": ticks * DT_S,
        "recording": "recording.rrd",
        "laws": {"leader": "path", "followers": {"2": "fuzzy (V_N dynamic)"}},
        "followers": {"2": {"acquired": True, "rms_m": 0.1, "max_m": 0.2}},
        **more,
    }


def fake_run(
    folder: Path,
    ticks: int = 20,
    summary: Mapping[str, Any] | None = None,
    own: Mapping[str, np.ndarray] | None = None,
    recording: bool = True,
    more: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """``folder`` made a run folder of ``ticks`` ticks: ``summary`` (default
    summary_of), the scenario and, with ``recording``, the recording, with
    R2's controller's ``own`` values (name -> one per tick) and ``more`` of
    R2's series (its path under robots/r2/ -> one per tick)."""
    folder.mkdir(parents=True)
    said = dict(summary) if summary is not None else summary_of(f"fake-{folder.name}", ticks)
    (folder / "summary.json").write_text(json.dumps(said))
    (folder / "scenario.toml").write_text(shipped()[SCENARIO].read_text())
    if recording:
        series = {f"controller/{name}": v for name, v in (own or {}).items()} | dict(more or {})
        _recording(folder / "recording.rrd", str(said["run_id"]), ticks, series)
    return folder


def _recording(path: Path, run_id: str, ticks: int, series: Mapping[str, np.ndarray]) -> None:
    import rerun as rr

    rec = rr.RecordingStream("formation-swarm", recording_id=run_id)
    rec.save(str(path))
    t = np.arange(ticks) * DT_S

    def column(entity: str, values: np.ndarray) -> None:
        cols = rr.Points2D.columns(positions=values) if values.ndim == 2 else rr.Scalars.columns(scalars=values)
        rec.send_columns(entity, indexes=[rr.TimeColumn("sim_time", duration=t)], columns=cols)

    leader = np.c_[np.zeros(ticks), 1.5 * t]
    follower = leader - [1.5, 1.5]
    target = follower + [0.0, 0.1]
    column("robots/r1/pose", leader)
    column("robots/r2/pose", follower)
    column("robots/r2/target/true", target)
    column("robots/r2/error/formation", np.full(ticks, 0.1))
    column("robots/r2/fis/v_n", np.full(ticks, 1.5))
    column("robots/r2/fis/rho", 0.1 + t)
    column("robots/r2/fis/alpha", -t)
    for name, values in series.items():
        column(f"robots/r2/{name}", np.asarray(values, dtype=float))
    rec.flush(timeout_sec=5.0)
    rec.disconnect()
