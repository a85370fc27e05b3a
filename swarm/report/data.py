"""A run folder as numpy arrays: ``load_run(RUN_DIR)``.

A run folder (``swarm run``, ``swarm sweep --logger``, the ``swarm_run``
fixture) holds ``recording.rrd``, written by the logger, and ``summary.json``.
``load_run`` reads both and returns a :class:`RunData`: one array per
quantity, indexed ``[robot, tick]``, robots in the order of ``RunData.robots``.
What a run did not record is NaN (a leader has no target, no V_N and no
wheel telemetry; an l-psi follower has no V_N; a tick the logger missed).

The recording stores positions as float32 (Rerun's 2-D points): poses and
target points are exact to about 1e-6 of their size; the errors and V_N are
float64, computed in float64 by the logger from the messages themselves.

``read_recording`` is the recording reader ``swarm report`` draws from too.
"""

from __future__ import annotations

import json
import math
import tomllib
import warnings
from collections import defaultdict
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

# The components read from a recording, first one present in a chunk wins:
# points (poses, targets), scalars (errors, V_N, wheels, codes), arrows (headings).
COLUMNS = ("Points2D:positions", "Scalars:scalars", "Arrows2D:vectors")
TIME_TOLERANCE_S = 1e-6  # a row belongs to the tick whose sim time is this close


class Series:
    """One entity's rows from the recording: times (s) and values, time-sorted."""

    def __init__(self, t: np.ndarray, v: np.ndarray) -> None:
        order = np.argsort(t, kind="stable")
        self.t, self.v = t[order], v[order]

    def __len__(self) -> int:
        return len(self.t)


def read_recording(path: Path) -> dict[str, Series]:
    """Every point, scalar and arrow entity of a recording, by entity path
    (arrows: their vectors)."""
    from rerun.chunk import RrdReader

    times: dict[str, list[np.ndarray]] = defaultdict(list)
    values: dict[str, list[np.ndarray]] = defaultdict(list)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a recording cut by a kill has no footer: still readable
        chunks = list(RrdReader(str(path)).stream())
    for ch in chunks:
        rb = ch.to_record_batch()
        names = rb.schema.names
        if "sim_time" not in names:
            continue
        col = next((n for n in COLUMNS if n in names), None)
        if col is None:
            continue
        t = rb.column("sim_time").cast("int64").to_numpy(zero_copy_only=False) / 1e9
        rows = rb.column(col).to_pylist()
        keep = [i for i, r in enumerate(rows) if r]
        entity = str(ch.entity_path)
        times[entity].append(t[keep])
        values[entity].append(np.array([r[0] for i, r in enumerate(rows) if r], dtype=float))
    return {e: Series(np.concatenate(times[e]), np.concatenate(values[e])) for e in times}


def robots_in(data: Mapping[str, Series]) -> list[int]:
    ids = {int(e.split("/")[2][1:]) for e in data if e.startswith("/robots/r") and e.endswith("/pose")}
    return sorted(ids)


@dataclass(frozen=True)
class RunData:
    """One run, per robot per tick. Arrays are indexed ``[robot, tick]`` (plus a
    last axis for points), the robot axis in the order of ``robots``; NaN where
    the run recorded nothing (see the module's docstring)."""

    run_dir: Path
    scenario: str  # the scenario's name (run.name)
    seed: int | None
    summary: Mapping[str, Any]  # summary.json as written by the run
    config: Mapping[str, Any]  # scenario.toml as run, its tables as read ({} if the folder has none)
    dt_s: float  # s per tick
    robots: tuple[int, ...]  # robot ids
    followers: tuple[int, ...]  # those with a formation error (every robot but the leader)
    tick: np.ndarray  # (T,) int: the world's tick number
    time_s: np.ndarray  # (T,) s: sim time of the tick
    pose: np.ndarray  # (R, T, 3): x m, y m, heading rad (true, world frame)
    target_true: np.ndarray  # (R, T, 2) m: the true virtual target (eq. 1-6 on the true poses)
    target_ekf: np.ndarray  # (R, T, 2) m: the EKF's estimate of it, world frame
    target_measured: np.ndarray  # (R, T, 2) m: the target from the raw camera reading
    formation_error_m: np.ndarray  # (R, T) m: |position - true target|
    ekf_error_m: np.ndarray  # (R, T) m: |EKF estimate - true target|
    measured_error_m: np.ndarray  # (R, T) m: |measured target - true target|
    v_n_mps: np.ndarray  # (R, T) m/s: FIS-2's normal speed V_N
    wheels_mps: np.ndarray  # (R, T, 2) m/s: commanded left and right wheel speeds
    formation: np.ndarray  # (R, T) int: formation code flown, -1 where unknown (leaders)

    def index(self, robot: int) -> int:
        """The row of ``robot`` (its id) in the arrays."""
        try:
            return self.robots.index(robot)
        except ValueError:
            raise ValueError(f"robot must be one of {list(self.robots)}, got {robot!r}") from None


def read_folder(run_dir: str | Path, need_recording: bool = True) -> tuple[Path, dict[str, Any], dict[str, Series]]:
    """A run folder's path, summary and recording; ValueError naming what is missing
    (``need_recording=False``: a folder without recording.rrd gives no series)."""
    run_dir = Path(run_dir)
    summary_path, rrd = run_dir / "summary.json", run_dir / "recording.rrd"
    if not run_dir.is_dir():
        what = "a file, not a run folder" if run_dir.exists() else "no such folder"
        raise ValueError(f"{run_dir}: {what}")
    if not summary_path.is_file():
        raise ValueError(f"{run_dir} is not a run folder: no summary.json")
    try:
        summary = json.loads(summary_path.read_text())
    except ValueError as exc:
        raise ValueError(f"{summary_path} is not valid JSON: {exc}") from None
    if not isinstance(summary, dict) or not isinstance(summary.get("run_id"), str):
        raise ValueError(f"{summary_path} is not a run summary (a JSON object with the run's run_id)")
    if not rrd.is_file():
        if not need_recording:
            return run_dir, summary, {}
        raise ValueError(f"{run_dir} has no recording.rrd: run it with its logger (without --no-logger)")
    try:
        data = read_recording(rrd)
        runs = {entry.recording_id for entry in _entries(rrd) if entry.kind == "recording"}
    except RuntimeError as exc:  # rerun's reader: a file cut before its first chunk, or not a recording
        raise ValueError(f"cannot read {rrd}: {exc}") from None
    if runs and summary["run_id"] not in runs:  # the logger names its recording after the run
        raise ValueError(
            f"{rrd} is the recording of run {', '.join(sorted(runs))}, not of {summary['run_id']} (summary.json): "
            "the two come from different runs"
        )
    return run_dir, summary, data


def _entries(rrd: Path) -> list[Any]:
    """The stores a recording file holds (application and recording ids)."""
    from rerun.chunk import RrdReader

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a recording cut by a kill has no footer: still readable
        return list(RrdReader(str(rrd)).recordings())


def load_run(run_dir: str | Path) -> RunData:
    """Reads RUN_DIR/recording.rrd and summary.json into a :class:`RunData`.
    Raises ValueError for a folder it cannot use (missing, not a run folder,
    no recording, a recording without a robot pose)."""
    run_dir, summary, data = read_folder(run_dir)
    robots = robots_in(data)
    if not robots:
        raise ValueError(f"{run_dir / 'recording.rrd'} holds no robot poses (did the run reach its first tick?)")
    config = _config(run_dir)
    times = np.unique(np.concatenate([data[f"/robots/r{r}/pose"].t for r in robots]))
    dt_s = _dt(config, times)
    n_r, n_t = len(robots), len(times)

    def grid(entity: str, width: int = 0) -> np.ndarray:
        out = np.full((n_r, n_t, width) if width else (n_r, n_t), np.nan)
        for i, r in enumerate(robots):
            s = data.get(f"/robots/r{r}/{entity}")
            if s is not None and len(s):
                at, ok = _ticks_of(s.t, times)
                out[i, at[ok]] = s.v[ok]
        return out

    heading_vec = grid("heading", 2)
    pose = np.concatenate([grid("pose", 2), np.arctan2(heading_vec[..., 1], heading_vec[..., 0])[..., None]], axis=-1)
    codes = grid("formation")  # logged when it changes: carried forward to the next change
    formation = np.full((n_r, n_t), -1, dtype=int)
    for i in range(n_r):
        known = ~np.isnan(codes[i])
        last = np.maximum.accumulate(np.where(known, np.arange(n_t), -1))
        formation[i] = np.where(last >= 0, codes[i][np.maximum(last, 0)], -1)
    return RunData(
        run_dir=run_dir,
        scenario=str(summary.get("scenario") or config.get("run", {}).get("name", "")),
        seed=summary.get("seed") if isinstance(summary.get("seed"), int) else None,
        summary=summary,
        config=config,
        dt_s=dt_s,
        robots=tuple(robots),
        followers=tuple(r for r in robots if f"/robots/r{r}/error/formation" in data),
        tick=np.rint(times / dt_s).astype(int),
        time_s=times,
        pose=pose,
        target_true=grid("target/true", 2),
        target_ekf=grid("ekf/target", 2),
        target_measured=grid("target/measured", 2),
        formation_error_m=grid("error/formation"),
        ekf_error_m=grid("error/ekf"),
        measured_error_m=grid("error/measured"),
        v_n_mps=grid("fis/v_n"),
        wheels_mps=np.stack([grid("wheels/left"), grid("wheels/right")], axis=-1),
        formation=formation,
    )


def _ticks_of(t: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each time in ``t``, its index in the sorted ``times`` and whether it is one of them."""
    at = np.clip(np.searchsorted(times, t), 0, len(times) - 1)
    before = np.clip(at - 1, 0, len(times) - 1)
    at = np.where(np.abs(times[before] - t) < np.abs(times[at] - t), before, at)
    return at, np.abs(times[at] - t) <= TIME_TOLERANCE_S


def _config(run_dir: Path) -> dict[str, Any]:
    """The scenario as run, as its TOML tables; {} when the folder has none or it does not parse."""
    try:
        return tomllib.loads((run_dir / "scenario.toml").read_text())
    except (OSError, ValueError):
        return {}


def _dt(config: Mapping[str, Any], times: np.ndarray) -> float:
    """The tick length: the scenario's run.dt_s, else the smallest step between recorded ticks."""
    dt = (config.get("run") or {}).get("dt_s")
    if isinstance(dt, (int, float)) and not isinstance(dt, bool) and math.isfinite(dt) and dt > 0:
        return float(dt)
    steps = np.diff(times)
    return float(steps[steps > 0].min()) if np.any(steps > 0) else 1.0
