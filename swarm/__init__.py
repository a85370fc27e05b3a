"""Distributed leader-follower formation emulator (vision, fuzzy control, EKF).

``from formation_swarm import load_run``: a run folder as numpy arrays
(``formation_swarm.data``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

if TYPE_CHECKING:
    from formation_swarm.data import RunData, load_run

__all__ = ["RunData", "__version__", "load_run"]


def __getattr__(name: str) -> Any:
    # Imported on first use: every process imports this package, few read recordings.
    if name in ("load_run", "RunData"):
        from formation_swarm import data

        return getattr(data, name)
    raise AttributeError(f"module 'formation_swarm' has no attribute {name!r}")
