"""What lets a caller drive robots of an engine's run: each follower's
controller input kept as the role hands it over (:class:`Watched`), and
wheel speeds given for a tick checked before they replace a robot's
command (:func:`checked_actions`)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

from formation_swarm.agents.controller import FollowerController, FollowerInput, FollowerOutput


class Watched:
    """A follower's controller, its every input kept in ``inputs`` under its
    robot id before the step is handed on unchanged. The role keeps the
    controller's own ``prepare`` (bound when it was built), so nothing else
    of the law's tick changes."""

    def __init__(self, law: FollowerController, robot_id: int, inputs: dict[int, FollowerInput]) -> None:
        self.law = law
        self.robot_id = robot_id
        self.inputs = inputs

    def step(self, inp: FollowerInput) -> FollowerOutput:
        self.inputs[self.robot_id] = inp
        return self.law.step(inp)


def checked_actions(
    actions: Mapping[Any, Any], robots: Iterable[int], max_wheel_mps: float
) -> dict[int, tuple[float, float]]:
    """``actions`` as {robot id: (left_mps, right_mps)}; ValueError naming the
    robot and the value for an id that is no robot of the run, or speeds that
    are not two finite numbers within ``max_wheel_mps`` either way."""
    if not isinstance(actions, Mapping):
        raise ValueError(f"actions must map robot ids to (left_mps, right_mps), got {type(actions).__name__}")
    ids = set(robots)
    out: dict[int, tuple[float, float]] = {}
    for rid, wheels in actions.items():
        if isinstance(rid, bool) or not isinstance(rid, int) or rid not in ids:
            raise ValueError(f"actions: {rid!r} is not a robot of this run; robots are {sorted(ids)}")
        try:
            left, right = (float(v) for v in wheels)
        except (TypeError, ValueError):
            raise ValueError(f"actions[{rid}] must be two wheel speeds (left_mps, right_mps), got {wheels!r}") from None
        for name, v in (("left_mps", left), ("right_mps", right)):
            if not (math.isfinite(v) and abs(v) <= max_wheel_mps):
                raise ValueError(
                    f"actions[{rid}] {name} must be a finite number within +-{max_wheel_mps:g} m/s"
                    f" (robot.max_wheel_mps), got {v!r}"
                )
        out[rid] = (left, right)
    return out
