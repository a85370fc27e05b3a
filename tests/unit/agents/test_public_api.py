"""The follower controller API as a user imports it: every name from
``formation_swarm`` itself, none of them loading Zenoh, Rerun or the
launcher."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import pytest

import formation_swarm
from formation_swarm.agents import controller

CONTROLLER_API = (
    "ControllerSetup",
    "FollowerController",
    "FollowerInput",
    "FollowerOutput",
    "FollowerParams",
    "MarkerReading",
    "Point",
    "Slot",
    "TargetEstimate",
)

PROBE = f"""
import json, sys
from formation_swarm import {", ".join(CONTROLLER_API)}
print(json.dumps(sorted(m for m in ("zenoh", "rerun", "formation_swarm.launch.launcher") if m in sys.modules)))
"""


def test_the_controller_api_is_the_packages_own() -> None:
    assert set(CONTROLLER_API) <= set(formation_swarm.__all__)
    for name in CONTROLLER_API:
        assert getattr(formation_swarm, name) is getattr(controller, name), name


def test_importing_it_loads_neither_zenoh_nor_rerun() -> None:
    res = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout) == []


def test_its_records_are_frozen_and_taken_by_keyword() -> None:
    """A reading, an output and a target: positional arguments are refused,
    fields cannot be set."""
    reading = formation_swarm.MarkerReading(rho_m=2.0, phi_rad=0.1, beta_rad=-0.2)
    target = formation_swarm.TargetEstimate(x_m=0.5, y_m=1.5)
    out = formation_swarm.FollowerOutput(left_mps=1.0, right_mps=1.25, target=target)
    assert (out.stop, dict(out.values), target.cov_m2) == (None, {}, None)
    with pytest.raises(TypeError):
        formation_swarm.MarkerReading(2.0, 0.1, -0.2)  # type: ignore[misc]
    with pytest.raises(TypeError):
        formation_swarm.FollowerOutput(1.0, 1.0)  # type: ignore[misc]
    for record, field in ((reading, "rho_m"), (out, "left_mps"), (target, "x_m")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(record, field, 0.0)
