"""The pytest plugin is loaded in every pytest session of an environment where
the package is installed (its ``pytest11`` entry point): it must cost such a
session nothing until a test uses one of its fixtures."""

from __future__ import annotations

import json
import subprocess
import sys

PROBE = """
import json, sys
import formation_swarm.pytest_plugin
print(json.dumps(sorted(m for m in ("formation_swarm.launch.launcher", "zenoh") if m in sys.modules)))
"""


def test_importing_the_plugin_imports_neither_the_launcher_nor_zenoh() -> None:
    res = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout) == []
