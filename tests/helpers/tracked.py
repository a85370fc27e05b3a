"""A fresh copy of the repository as a user gets it: its tracked files only."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

from tests.helpers import ROOT


def copy_tracked(dest: Path) -> Path:
    """Copy every file ``git ls-files`` lists into ``dest`` (no .venv, runs/ or
    build output of this working tree) and return ``dest``. Files deleted but
    not yet committed are left out."""
    listed = subprocess.run(
        ["git", "ls-files", "-z"], cwd=ROOT, check=True, capture_output=True, text=True
    ).stdout.split("\0")
    for name in filter(None, listed):
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    return dest
