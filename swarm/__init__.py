"""Distributed leader-follower formation emulator (vision, fuzzy control, EKF).

The public API, imported on first use (every process imports this package;
few need any of it):

- ``load_run(folder) -> RunData``: a run folder as numpy arrays.
- ``Launch(scenario, ...)``: start a run's processes, watch them, ``wait()``
  for its ``RunResult``.
- ``Engine(scenario, ...)``: the same run in this process, lockstep, no
  Zenoh: ``step()``, ``run() -> EngineResult``, ``reset(seed)``; its
  trajectory digest is the distributed run's.
- the pytest fixtures ``swarm_run`` and ``swarm_launch`` (the ``pytest11``
  entry point ``formation_swarm.pytest_plugin``).
- the follower controller API: ``FollowerController`` and what it takes and
  gives (``ControllerSetup``, ``FollowerParams``, ``Slot``, ``Point``,
  ``FollowerInput``, ``MarkerReading``, ``FollowerOutput``,
  ``TargetEstimate``), docs/controllers.md, and ``check_controller``, which
  tries a controller as ``swarm check-controller`` does.
- the leader's policy API: ``LeaderPolicy`` and what it takes and gives
  (``LeaderSetup``, ``LeaderParams``, ``LeaderSensing``, ``LeaderMove``,
  ``Pose``), docs/leader-policy.md.

Everything else (``formation_swarm.spec``, ``.runtime``, ``.nodes``, ...) is
internal: docs/architecture.md draws the layers.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from formation_swarm.common.version import __version__

if TYPE_CHECKING:
    from formation_swarm.agents.controller import (
        ControllerSetup,
        FollowerController,
        FollowerInput,
        FollowerOutput,
        FollowerParams,
        MarkerReading,
        Point,
        Slot,
        TargetEstimate,
    )
    from formation_swarm.agents.leader_policy import (
        LeaderMove,
        LeaderParams,
        LeaderPolicy,
        LeaderSensing,
        LeaderSetup,
        Pose,
    )
    from formation_swarm.engine import Engine, EngineResult
    from formation_swarm.engine.check import check_controller
    from formation_swarm.launch.launcher import Launch, RunResult
    from formation_swarm.report.data import RunData, load_run

_PUBLIC = {
    "load_run": "formation_swarm.report.data",
    "RunData": "formation_swarm.report.data",
    "Launch": "formation_swarm.launch.launcher",
    "RunResult": "formation_swarm.launch.launcher",
    "Engine": "formation_swarm.engine",
    "EngineResult": "formation_swarm.engine",
    "check_controller": "formation_swarm.engine.check",
    **dict.fromkeys(
        ("LeaderMove", "LeaderParams", "LeaderPolicy", "LeaderSensing", "LeaderSetup", "Pose"),
        "formation_swarm.agents.leader_policy",
    ),
    **dict.fromkeys(
        (
            "ControllerSetup",
            "FollowerController",
            "FollowerInput",
            "FollowerOutput",
            "FollowerParams",
            "MarkerReading",
            "Point",
            "Slot",
            "TargetEstimate",
        ),
        "formation_swarm.agents.controller",
    ),
}

__all__ = [
    "ControllerSetup",
    "Engine",
    "EngineResult",
    "FollowerController",
    "FollowerInput",
    "FollowerOutput",
    "FollowerParams",
    "Launch",
    "LeaderMove",
    "LeaderParams",
    "LeaderPolicy",
    "LeaderSensing",
    "LeaderSetup",
    "MarkerReading",
    "Point",
    "Pose",
    "RunData",
    "RunResult",
    "Slot",
    "TargetEstimate",
    "__version__",
    "check_controller",
    "load_run",
]


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        return getattr(importlib.import_module(_PUBLIC[name]), name)
    raise AttributeError(f"module 'formation_swarm' has no attribute {name!r}")
