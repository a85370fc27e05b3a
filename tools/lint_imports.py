"""Check the import contracts of pyproject.toml ([tool.importlinter]) on the
package as it installs.

The repository maps one import package from several folders (swarm/ is
formation_swarm, agents/ is formation_swarm.agents, ...). import-linter finds a
package's modules by walking its folder, so it would see swarm/ alone: this
lays the tree out as a wheel installs it, in a temporary folder, and runs
lint-imports there. Extra arguments go to lint-imports.

    python tools/lint_imports.py [--verbose]
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def lay_out(dest: Path) -> None:
    """The package's folders copied where an installed wheel has them."""
    setup = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    for package, folder in sorted(setup["package-dir"].items()):
        target = dest.joinpath(*package.split("."))
        shutil.copytree(ROOT / folder, target, ignore=shutil.ignore_patterns("__pycache__"), dirs_exist_ok=True)


def main(argv: list[str]) -> int:
    lint = Path(sys.executable).with_name("lint-imports")
    with tempfile.TemporaryDirectory(prefix="lint-imports-") as tmp:
        lay_out(Path(tmp))
        env = {**os.environ, "PYTHONPATH": tmp, "PYTHONDONTWRITEBYTECODE": "1"}
        config = ROOT / "pyproject.toml"
        return subprocess.run([str(lint), str(config), "--no-cache", *argv], cwd=tmp, env=env).returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
