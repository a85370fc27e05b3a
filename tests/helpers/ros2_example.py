"""examples/ros2_follower's ROS-free modules, imported by path (the folder is no package)."""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType

from tests.helpers import ROOT

EXAMPLE = ROOT / "examples" / "ros2_follower"


def load(name: str) -> ModuleType:
    """``examples/ros2_follower/<name>.py`` as a module (``pursuit``, ``session_config``)."""
    spec = importlib.util.spec_from_file_location(f"ros2_follower_{name}", EXAMPLE / f"{name}.py")
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {EXAMPLE / name}.py")
    if spec.name not in sys.modules:
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # NamedTuple classes look their module up
        spec.loader.exec_module(module)
    return sys.modules[spec.name]
