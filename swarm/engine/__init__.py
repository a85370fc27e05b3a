"""One lockstep run in one process, public (``from formation_swarm import
Engine``): what a controller's tests, the learning adapters and replay use,
and ``swarm sim``'s engine.

``Engine(scenario, seed=..., overrides=..., faults=...)`` drives the same
objects as a distributed run (the world's tick, every robot's role, the
link layer), so its trajectory digest is ``swarm run --mode lockstep``'s
for the same scenario, seed and faults (core). engine.agents holds the
robots' agents, engine.faults the faults it takes, engine.result what a
run gives (``EngineResult``).
"""

from __future__ import annotations

from formation_swarm.engine.core import Engine
from formation_swarm.engine.result import EngineResult

__all__ = ["Engine", "EngineResult"]
