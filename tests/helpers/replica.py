"""A lockstep run replayed in one process: formation_swarm.engine's Engine,
which drives the world's tick and every robot's role as the processes do,
without Zenoh. Its trajectory digest is the distributed run's, bit for bit
(tests/system/test_engine.py and test_distributed.py check it against real
runs), so the published figures are recomputed in seconds by
tests/unit/studies/test_published.py and by mutation testing.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from formation_swarm import Engine


def replay(path: str | Path, seed: int, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The world's summary of the lockstep run of a scenario with this seed."""
    return Engine(path, seed=seed, overrides=overrides).run().world
