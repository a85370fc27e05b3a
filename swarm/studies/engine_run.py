"""One run of a scenario in this process (formation_swarm.engine), with what
``swarm run``'s logger would add to its summary: each follower's target
errors and the EKF's NEES (world.metrics.TargetErrors), from the telemetry
the roles answer with, joined with the true poses of its tick as the
logger joins them. Its trajectory digest is the lockstep run's, so a study
of many seeds takes minutes instead of hours; what it cannot have is what
depends on processes' timing (a lockstep miss, a logger).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from formation_swarm.agents.role_base import Answer
from formation_swarm.engine import Engine
from formation_swarm.protocol.messages import Telemetry
from formation_swarm.world.kinematics import from_body_frame
from formation_swarm.world.metrics import TargetErrors, target_in

NAN2 = (np.nan, np.nan)


class _Tapped(Engine):
    """An engine whose roles' telemetry is kept, tick by tick, as the logger would get it."""

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self.telemetry: list[Telemetry] = []
        agents = self._agents
        answer = agents.answer

        def tapped(rid: int, payload: bytes) -> Answer | None:
            out = answer(rid, payload)
            if out is not None and out.telemetry is not None:
                self.telemetry.append(out.telemetry)
            return out

        agents.answer = tapped  # type: ignore[method-assign]


def _row(sc: Any, tel: Telemetry, poses: Mapping[int, Any]) -> list[float]:
    """Pose, true target (that of the formation the telemetry names), measured and
    estimated targets (world frame) and covariance of one follower's tick."""
    pose = poses[tel.sender]
    try:
        target = target_in(sc, tel.sender, tel.formation, poses)
    except (IndexError, KeyError):
        target = NAN2
    measured = from_body_frame(pose, *tel.measured) if tel.measured else NAN2
    estimate = from_body_frame(pose, *tel.estimate) if tel.estimate else NAN2
    return [
        *pose,
        *target,
        *measured,
        *estimate,
        *(tel.target_cov or (np.nan,) * 3),
        np.nan if tel.vn is None else tel.vn,
    ]


def run(
    scenario: str | Path,
    seed: int,
    overrides: Mapping[str, Any] | None = None,
    faults: Sequence[str] = (),
) -> tuple[dict[str, Any], dict[int, np.ndarray]]:
    """The run's summary (``swarm run``'s keys, ``parts.logger.target_errors``
    filled in) and each follower's V_N every tick it answered (NaN: none);
    ``faults`` are added to the scenario's (docs/faults.md's grammar)."""
    eng = _Tapped(scenario, seed=seed, overrides=dict(overrides or {}), faults=list(faults))
    rows: dict[int, list[list[float]]] = defaultdict(list)
    sc = eng.scenario
    while eng.observe():
        poses = eng.poses
        for tel in eng.telemetry:
            rows[tel.sender].append(_row(sc, tel, poses))
        eng.telemetry.clear()
        eng.step()
    summary = dict(eng.run().summary)
    eng.close()
    errors: dict[str, Any] = {}
    vn: dict[int, np.ndarray] = {}
    for rid, rr in sorted(rows.items()):
        a = np.array(rr, dtype=float)
        acc = TargetErrors()
        acc.add(a[:, 0:3], a[:, 3:5], a[:, 5:7], a[:, 7:9], a[:, 9:12])
        errors[str(rid)] = acc.stats()
        vn[rid] = a[:, 12]
    parts = dict(summary.get("parts") or {})
    parts["logger"] = {"target_errors": errors}
    summary["parts"] = parts
    return summary, vn
