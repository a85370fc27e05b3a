"""One colour per robot, the same in the Rerun viewer and in the report's figures.

Colours are RGB tuples of floats in [0, 1]: matplotlib takes them as they
are, and Rerun reads float colours as [0, 1] too. Red and grey are left
out: they draw the obstacles and the leader's path.
"""

from __future__ import annotations

RGB = tuple[float, float, float]

# matplotlib's tab10 without its red and grey.
_ROBOTS: tuple[RGB, ...] = tuple(
    (int(h[0:2], 16) / 255, int(h[2:4], 16) / 255, int(h[4:6], 16) / 255)
    for h in ("1f77b4", "ff7f0e", "2ca02c", "9467bd", "8c564b", "e377c2", "bcbd22", "17becf")
)
OBSTACLE: RGB = (0.84, 0.15, 0.16)
PATH: RGB = (0.5, 0.5, 0.5)


def robot_colour(robot_id: int) -> RGB:
    """Robot ``robot_id``'s colour: ids 1, 2, ... take the palette in turn."""
    return _ROBOTS[(robot_id - 1) % len(_ROBOTS)]


def series_colour(index: int) -> RGB:
    """The colour of a figure's ``index``-th line when its lines are not robots (controllers, claims)."""
    return _ROBOTS[index % len(_ROBOTS)]


def lighter(colour: RGB, amount: float = 0.5) -> RGB:
    """``colour`` mixed with white: a robot's second series (raw vs EKF, right wheel)."""
    r, g, b = colour
    return (r + (1 - r) * amount, g + (1 - g) * amount, b + (1 - b) * amount)
