"""Imports point one way: the maths and the wire load neither Zenoh nor the
command-line/launcher layer, and the package installs one import name."""

from __future__ import annotations

import json
import subprocess
import sys

PURE = (
    "formation_swarm.agents.ekf",
    "formation_swarm.agents.follower",
    "formation_swarm.agents.fuzzy",
    "formation_swarm.agents.avoidance",
    "formation_swarm.agents.formation",
    "formation_swarm.agents.leader",
    "formation_swarm.agents.pilot",
    "formation_swarm.agents.lpsi",
    "formation_swarm.world.kinematics",
    "formation_swarm.world.camera",
    "formation_swarm.world.engine",
    "formation_swarm.world.hardware_faults",
    "formation_swarm.world.recovery",
    "formation_swarm.world.process_faults",
    "formation_swarm.protocol.keys",
    "formation_swarm.protocol.links",
    "formation_swarm.protocol.codec",
    "formation_swarm.protocol.batch",
    "formation_swarm.protocol.messages",
)
APPLICATION = (
    "formation_swarm.cli",
    "formation_swarm.launcher",
    "formation_swarm.scenario",
    "formation_swarm.proc",
    "formation_swarm.role",
    "formation_swarm.summary",
)


def loaded_after_import(modules: tuple[str, ...]) -> set[str]:
    code = "import importlib, json, sys\n"
    code += "".join(f"importlib.import_module({m!r})\n" for m in modules)
    code += "print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60)
    return set(json.loads(out.stdout))


def test_the_maths_and_the_wire_load_no_zenoh_and_no_application_layer() -> None:
    loaded = loaded_after_import(PURE)
    assert not {m for m in loaded if m == "zenoh" or m.startswith("zenoh.")}
    assert not loaded & set(APPLICATION)
    # and the package's own folders are not importable under their folder names
    assert not loaded & {"agents", "world", "protocol", "swarm"}
