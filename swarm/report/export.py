"""One row per robot per tick of a run folder, as CSV or Parquet; or the run
as ROS 2 messages in an MCAP file (--mcap).

Reads RUN_DIR/recording.rrd and summary.json (formation_swarm.load_run)
and writes a table (default: RUN_DIR/run.csv or RUN_DIR/run.parquet), the
rows robot by robot, tick by tick. Columns and units:

    robot                         robot id
    tick, time_s                  the world's tick and its sim time, s
    x_m, y_m, heading_rad         true pose
    target_x_m, target_y_m        true virtual target (followers)
    ekf_x_m, ekf_y_m              the EKF's estimate of it
    measured_x_m, measured_y_m    the target from the raw camera reading
    formation_error_m             |position - true target|
    ekf_error_m, measured_error_m |estimate or reading - true target|
    v_n_mps                       FIS-2's normal speed V_N
    left_mps, right_mps           commanded wheel speeds (followers)
    formation                     formation code flown (followers)
    rho_m, alpha_rad              the controller's distance and heading errors (eq. 5, 4)
    steering_to, changing         eq. 13's target and a formation change under way, when recorded
    controller_<name>             each of the controller's own values (docs/controllers.md)

A value the run did not record is empty in CSV and null in Parquet.

--mcap writes RUN_DIR/run.mcap: the topics a ROS 2 node sees of a live run
(/clock, /tf, /robotN/odom, /robotN/camera, /formation,
/robotN/formation_error; docs/ros2.md), one message per tick, stamped with
sim time, with ROS 2 Jazzy schemas, as rosbag2 writes them. It needs the
ros2 extra (pip install 'formation-swarm[ros2]').

Every file is written beside its name and renamed to it once complete. The
default file is the run's own, made from the run folder alone: an export
makes it again over the one there (and says so), as swarm report draws its
figures again. A file named by --out, which may be anyone's, that exists
already is left alone unless --force.
"""

from __future__ import annotations

import csv
import math
import os
import sys
from pathlib import Path

import numpy as np

from formation_swarm.agents.controller import WIRE_VALUES
from formation_swarm.report.data import RunData, load_run
from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser

FORMATS = ("csv", "parquet", "mcap")


def table(run: RunData) -> dict[str, np.ndarray]:
    """The run's columns (name -> one value per robot per tick), robot-major."""
    n_r, n_t = len(run.robots), len(run.tick)

    def flat(a: np.ndarray) -> np.ndarray:
        return a.reshape(n_r * n_t)

    return {
        "robot": np.repeat(np.array(run.robots, dtype=int), n_t),
        "tick": np.tile(run.tick, n_r),
        "time_s": np.tile(run.time_s, n_r),
        "x_m": flat(run.pose[..., 0]),
        "y_m": flat(run.pose[..., 1]),
        "heading_rad": flat(run.pose[..., 2]),
        "target_x_m": flat(run.target_true[..., 0]),
        "target_y_m": flat(run.target_true[..., 1]),
        "ekf_x_m": flat(run.target_ekf[..., 0]),
        "ekf_y_m": flat(run.target_ekf[..., 1]),
        "measured_x_m": flat(run.target_measured[..., 0]),
        "measured_y_m": flat(run.target_measured[..., 1]),
        "formation_error_m": flat(run.formation_error_m),
        "ekf_error_m": flat(run.ekf_error_m),
        "measured_error_m": flat(run.measured_error_m),
        "v_n_mps": flat(run.v_n_mps),
        "left_mps": flat(run.wheels_mps[..., 0]),
        "right_mps": flat(run.wheels_mps[..., 1]),
        "formation": flat(run.formation),
        **{column(name): flat(values) for name, values in run.controller.items()},
    }


def column(name: str) -> str:
    """A controller value's column: its own name for the values the wire
    carries in its own fields (rho_m, alpha_rad, ...), else
    ``controller_<name>``, apart from the other columns."""
    return name if name in WIRE_VALUES else f"controller_{name}"


def write_csv(columns: dict[str, np.ndarray], path: Path) -> None:
    """The table as CSV: floats at full precision (they read back equal), missing values empty."""
    names = list(columns)
    cells = [[_cell(name, v) for v in col.tolist()] for name, col in columns.items()]
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        w.writerows(zip(*cells, strict=True))


def _cell(name: str, v: float | int) -> str:
    if name == "formation" and v < 0:
        return ""
    if isinstance(v, float) and math.isnan(v):
        return ""
    return repr(v)


def write_parquet(columns: dict[str, np.ndarray], path: Path) -> None:
    """The table as Parquet: float64 columns with nulls where the run recorded nothing."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays = {}
    for name, col in columns.items():
        missing = col < 0 if name == "formation" else np.isnan(col) if col.dtype.kind == "f" else None
        arrays[name] = pa.array(col, mask=missing)
    pq.write_table(pa.table(arrays), str(path))


def export(run_dir: str | Path, fmt: str = "csv", out: str | Path | None = None, force: bool = False) -> Path:
    """Writes the run's table (or MCAP file) and returns its path. ValueError for
    a folder it cannot use, an unknown format or an ``out`` that exists (unless
    ``force``), OSError when it cannot write."""
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    if out is not None and not force and (Path(out).exists() or Path(out).is_symlink()):
        raise ValueError(f"--out {out}: already exists; give another name, or --force to replace it")
    if fmt == "mcap":
        return _export_mcap(run_dir, out)
    run = load_run(run_dir)
    path = Path(out) if out is not None else run.run_dir / f"run.{fmt}"
    columns = table(run)
    part = path.with_name(f".{path.name}.part")
    try:
        (write_csv if fmt == "csv" else write_parquet)(columns, part)
        os.replace(part, path)
    finally:
        part.unlink(missing_ok=True)
    return path


def _export_mcap(run_dir: str | Path, out: str | Path | None) -> Path:
    try:
        from formation_swarm.report.ros2bag import export_mcap
    except ModuleNotFoundError as exc:
        extra = "pip install 'formation-swarm[ros2]'"
        raise ValueError(f"--mcap needs the ros2 extra ({exc.name} is missing): {extra}") from None
    run = load_run(run_dir)
    path = Path(out) if out is not None else run.run_dir / "run.mcap"
    export_mcap(run, path)
    return path


def build_parser() -> Parser:
    ap = Parser(
        prog="swarm export",
        description=__doc__,
        epilog="example:\n  swarm run fig11_obstacles --out runs/fig11\n"
        "  swarm export runs/fig11 --format parquet --out fig11.parquet\n"
        "  swarm export runs/fig11 --mcap --out fig11.mcap",
    )
    ap.add_argument("run_dir", metavar="RUN_DIR", help="a run's folder, as swarm run printed it (runs/<run id>)")
    ap.add_argument("--format", choices=FORMATS, default="csv", help="the file's format (default: csv)")
    ap.add_argument(
        "--mcap",
        dest="format",
        action="store_const",
        const="mcap",
        help="the same as --format mcap: the run's ROS 2 topics, as rosbag2 writes them",
    )
    ap.add_argument(
        "--out",
        default=None,
        metavar="FILE",
        help="the file to write (default: RUN_DIR/run.csv, run.parquet or run.mcap, the run's own file, "
        "made again over the one there)",
    )
    ap.add_argument(
        "--force", action="store_true", help="replace the file --out names if it exists (the default is replaced)"
    )
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    default = Path(args.run_dir) / f"run.{args.format}"
    again = args.out is None and default.is_file()  # the run's own file: made again, said so
    try:
        path = export(args.run_dir, args.format, args.out, force=args.force)
    except ValueError as exc:
        print(f"swarm export: {exc}", file=sys.stderr)
        return USAGE_ERROR
    except OSError as exc:
        print(f"swarm export: cannot write {args.out or 'the table'}: {exc}", file=sys.stderr)
        return USAGE_ERROR
    print(f"[export] {path}" + (" (made again over the one there)" if again else ""))
    return 0
