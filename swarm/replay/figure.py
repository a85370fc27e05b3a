"""The figure of a replay: one robot's wheel speeds as recorded and as replayed,
on the run's sim time, drawn as ``swarm report``'s time series are (the
robot's colour, ``series.gapped`` across the ticks it did not answer)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from formation_swarm.common.palette import robot_colour
from formation_swarm.protocol.messages import Command
from formation_swarm.report.figures import gapped
from formation_swarm.report.figures.drawing import save

DPI = 150


def _series(commands: Mapping[int, Command], dt_s: float, side: str) -> tuple[np.ndarray, np.ndarray]:
    ticks = sorted(commands)
    t = np.array(ticks, dtype=float) * dt_s
    v = np.array([getattr(commands[k], f"{side}_mps") for k in ticks], dtype=float)
    return gapped(t, v, dt_s)


def wheel_speeds(
    path: Path,
    recorded: Mapping[int, Command],
    replayed: Mapping[int, Command],
    *,
    robot: int,
    dt_s: float,
    title: str,
) -> None:
    """Both wheels' speeds of robot ``robot``, recorded (its colour) and replayed (dark, dashed), to ``path``."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 5), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    for ax, side in zip(axes, ("left", "right"), strict=True):
        ax.plot(*_series(recorded, dt_s, side), color=robot_colour(robot), lw=1.5, label="recorded")
        ax.plot(*_series(replayed, dt_s, side), color="0.15", lw=1.0, ls="--", label="replayed")
        ax.set_ylabel(f"{side} wheel, m/s")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    axes[-1].set_xlabel("time, s")
    fig.suptitle(title, fontsize=11)
    path.parent.mkdir(parents=True, exist_ok=True)
    save(fig, path, DPI)
