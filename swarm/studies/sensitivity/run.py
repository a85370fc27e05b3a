"""``swarm results --sensitivity``: every value of each axis run, then the
axis's figure and section; with ``--rows``, the axes' rows go into the CSV and
the summary of every claim along every axis in it is written too.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from formation_swarm.studies import sensitivity
from formation_swarm.studies.engine_sweep import run_engine_sweeps
from formation_swarm.studies.sections import markers, write_all
from formation_swarm.studies.sensitivity import figure as sensitivity_figure
from formation_swarm.studies.sensitivity import rows as sensitivity_rows
from formation_swarm.studies.sensitivity import text as sensitivity_text

WHERE = markers("where the claims hold")
# The rank swap along the axes, in the avoidance's section (not a claim of the paper).
SWAP = markers("rank swap along the axes")


def run(
    axes: Sequence[sensitivity.Axis],
    seeds: int,
    out: Path,
    *,
    workers: int | None,
    figures: Path,
    writes: Sequence[Path],
    rows_csv: Path | None = None,
) -> int:
    """Each axis's points, then its figure and its section (printed, and written into ``writes``)."""
    for n, axis in enumerate(axes, 1):
        points, point_rows = [], {}
        for k, value in enumerate(axis.values, 1):
            print(
                f"[sensitivity] {axis.title} = {axis.label(value)}: value {k} of {len(axis.values)}, "
                f"axis {n} of {len(axes)}",
                flush=True,
            )
            settings, faults = axis.point(value)
            sweeps = sensitivity.plan(range(seeds), settings, faults, out, workers=workers, extras=axis.extras)
            rows = run_engine_sweeps(sweeps, out)
            if rows is None:
                return 1
            points.append(sensitivity.measure(value, rows))
            point_rows[value] = rows
        png = figures / f"sensitivity-{axis.name}.png"
        sensitivity_figure.write_figure(png, axis, points)
        rel = png.relative_to(figures.parent) if figures.name == "figures" else png
        text = sensitivity_text.markdown(axis, points, str(rel))
        print(text)
        if not write_all(writes, text, *markers("sensitivity", axis.name)):
            return 1
        if rows_csv is not None:
            sensitivity_rows.merge(rows_csv, axis.name, point_rows)
    if rows_csv is None:
        return 0
    for text, marks in ((where_text(rows_csv), WHERE), (swap_text(rows_csv), SWAP)):
        print(text)
        if not write_all(writes, text, *marks):
            return 1
    return 0


def _found(rows_csv: Path) -> dict[str, tuple[sensitivity.Axis, list[sensitivity.Point]]]:
    """Every axis of the CSV, in the axes' order, with its points."""
    table = sensitivity_rows.read(rows_csv)
    return {
        a.name: (a, [sensitivity.measure(v, table[a.name][v]) for v in a.values if v in table[a.name]])
        for a in sensitivity.AXES
        if a.name in table
    }


def where_text(rows_csv: Path) -> str:
    """The summary of every claim along every axis of the CSV, in the axes' order."""
    return sensitivity_text.where(_found(rows_csv))


def swap_text(rows_csv: Path) -> str:
    """The rank swap along every axis of the CSV (the avoidance's section)."""
    return sensitivity_text.rank_swap(_found(rows_csv))
