"""A run folder as numpy arrays: ``load_run(RUN_DIR)``.

A run folder (``swarm run``, ``swarm sweep --logger``, the ``swarm_run``
fixture) holds ``recording.rrd``, written by the logger, and ``summary.json``.
``load_run`` reads both and returns a :class:`RunData`: one array per
quantity, indexed ``[robot, tick]``, robots in the order of ``RunData.robots``.
What a run did not record is NaN (a leader has no target, no V_N and no
wheel telemetry; an l-psi follower has no V_N; a tick the logger missed).
``RunData.controller`` holds the followers' controllers' named values by
name. The summary and the scenario as run are checked before anything is
read from them (report.inputs): a file that fails is a ValueError naming it.

The recording stores positions as float32 (Rerun's 2-D points): poses and
target points are exact to about 1e-6 of their size; the errors and V_N are
float64, computed in float64 by the logger from the messages themselves.

``read_recording`` is the recording reader ``swarm report`` draws from too.
"""

from __future__ import annotations

import math
import warnings
from collections import defaultdict
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from formation_swarm.agents.controller import STATS_VALUES, WIRE_VALUES
from formation_swarm.protocol.messages import EXTRA_NAME
from formation_swarm.report.inputs import read_scenario, read_summary

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

# The components read from a recording, first one present in a chunk wins:
# points (poses, targets), scalars (errors, V_N, wheels, codes), arrows (headings).
COLUMNS = ("Points2D:positions", "Scalars:scalars", "Arrows2D:vectors")
TIME_TOLERANCE_S = 1e-6  # a row belongs to the tick whose sim time is this close
MAX_OWN_VALUES = 256  # names of a controller's own values (at most 16 a tick, protocol.messages.MAX_EXTRAS)
KNOWN_NAMES = frozenset(WIRE_VALUES + STATS_VALUES)  # the role sends these in the message's own fields
# The wire's named values and where the logger records them; the first two are
# always columns (NaN where a law sends none), the others when a recording has them.
WIRE_ENTITIES = {
    "rho_m": "fis/rho",
    "alpha_rad": "fis/alpha",
    "steering_to": "fis/steering_to",
    "changing": "fis/changing",
}
ALWAYS = ("rho_m", "alpha_rad")


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
    summary: Mapping[str, Any]  # summary.json as written by the run (its fields checked: report.schema)
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
    # (R, T) each: the followers' controllers' named values (FollowerOutput.values) the recording
    # holds: rho_m and alpha_rad (eq. 4-5), steering_to and changing when recorded (WIRE_ENTITIES),
    # and each law's own, by name (docs/controllers.md).
    controller: Mapping[str, np.ndarray]

    @property
    def scenario(self) -> str:
        """The scenario's name (run.name)."""
        return str(self.summary.get("scenario") or (self.config.get("run") or {}).get("name", ""))

    @property
    def seed(self) -> int | None:
        seed = self.summary.get("seed")
        return seed if isinstance(seed, int) and not isinstance(seed, bool) else None

    def index(self, robot: int) -> int:
        """The row of ``robot`` (its id) in the arrays."""
        try:
            return self.robots.index(robot)
        except ValueError:
            raise ValueError(f"robot must be one of {list(self.robots)}, got {robot!r}") from None


class RunFolder(NamedTuple):
    """A run folder's files as read and checked (report.inputs)."""

    run_dir: Path
    summary: dict[str, Any]
    config: dict[str, Any]  # scenario.toml's tables ({}: the folder has none)
    scenario: Scenario | None  # the same, as the loader reads it
    data: dict[str, Series]  # the recording's series ({}: none, with need_recording=False)


def read_files(run_dir: str | Path) -> RunFolder:
    """A run folder's summary and scenario, checked (report.inputs), without
    its recording; ValueError naming what is missing or which file is wrong."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        what = "a file, not a run folder" if run_dir.exists() else "no such folder"
        raise ValueError(f"{run_dir}: {what}")
    if not (run_dir / "summary.json").exists():
        raise ValueError(f"{run_dir} is not a run folder: no summary.json")
    summary = read_summary(run_dir / "summary.json")
    config, scenario = read_scenario(run_dir / "scenario.toml") or ({}, None)
    return RunFolder(run_dir, summary, config, scenario, {})


def read_folder(run_dir: str | Path, need_recording: bool = True) -> RunFolder:
    """A run folder's summary, scenario and recording, each checked before
    anything is drawn or written; ValueError naming what is missing or what
    is wrong with which file (``need_recording=False``: a folder without
    recording.rrd gives no series)."""
    folder = read_files(run_dir)
    rrd, summary = folder.run_dir / "recording.rrd", folder.summary
    if not rrd.is_file():
        if not need_recording:
            return folder
        if summary.get("recording") is None:
            raise ValueError(f"{folder.run_dir} has no recording.rrd: run it with its logger (without --no-logger)")
        raise ValueError(f"{folder.run_dir} has no recording.rrd, though its summary names one: the file is missing")
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
    return folder._replace(data=data)


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
    run_dir, summary, config, _, data = read_folder(run_dir)
    robots = robots_in(data)
    if not robots:
        raise ValueError(f"{run_dir / 'recording.rrd'} holds no robot poses (did the run reach its first tick?)")
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
    recorded = {e.rpartition("/robots/r")[2].partition("/")[2] for e in data}  # "fis/rho", ...
    controller = {name: grid(entity) for name, entity in WIRE_ENTITIES.items() if name in ALWAYS or entity in recorded}
    try:
        own = own_values(data, robots)
    except ValueError as exc:
        raise ValueError(f"{run_dir / 'recording.rrd'} {exc}") from None
    controller |= {name: grid(f"controller/{name}") for name in own}
    return RunData(
        run_dir=run_dir,
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
        controller=controller,
    )


def own_values(data: Mapping[str, Series], robots: list[int]) -> list[str]:
    """The names of the controllers' own values in a recording
    (robots/r<id>/controller/<name>), sorted; a name the wire could not
    carry (protocol.messages.EXTRA_NAME) is not one. ValueError beyond
    MAX_OWN_VALUES names: more than a controller sends."""
    prefixes = tuple(f"/robots/r{r}/controller/" for r in robots)
    names = {e.rpartition("/")[2] for e in data if e.startswith(prefixes)}
    names = {n for n in names if EXTRA_NAME.fullmatch(n) and n not in KNOWN_NAMES}
    if len(names) > MAX_OWN_VALUES:
        raise ValueError(f"holds {len(names)} names of controllers' own values, more than {MAX_OWN_VALUES}")
    return sorted(names)


def _ticks_of(t: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each time in ``t``, its index in the sorted ``times`` and whether it is one of them."""
    at = np.clip(np.searchsorted(times, t), 0, len(times) - 1)
    before = np.clip(at - 1, 0, len(times) - 1)
    at = np.where(np.abs(times[before] - t) < np.abs(times[at] - t), before, at)
    return at, np.abs(times[at] - t) <= TIME_TOLERANCE_S


def _dt(config: Mapping[str, Any], times: np.ndarray) -> float:
    """The tick length: the scenario's run.dt_s, else the smallest step between recorded ticks."""
    dt = (config.get("run") or {}).get("dt_s")
    if isinstance(dt, (int, float)) and not isinstance(dt, bool) and math.isfinite(dt) and dt > 0:
        return float(dt)
    steps = np.diff(times)
    return float(steps[steps > 0].min()) if np.any(steps > 0) else 1.0
