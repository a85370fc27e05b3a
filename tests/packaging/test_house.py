"""The house's size rules hold: tools/house.py finds no file, function or
class over its bound, and no `# fmt: skip` lays out the product by hand."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.helpers import ROOT

PRODUCT = ("swarm", "agents", "world", "protocol")


def test_no_file_function_or_class_is_over_its_bound() -> None:
    res = subprocess.run([sys.executable, str(ROOT / "tools" / "house.py")], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout
    assert res.stdout.strip() == "no breaches"


def test_a_long_function_is_a_breach(tmp_path: Path) -> None:
    long = tmp_path / "long.py"
    long.write_text("def f():\n" + "    x = 1\n" * 61)
    sys.path.insert(0, str(ROOT / "tools"))
    import house

    found = list(house.breaches(long, root=tmp_path))
    assert found == ["long.py:1: function f is 62 lines (at most 60)"]


def test_the_formatter_lays_out_the_product() -> None:
    skips = [
        f"{path.relative_to(ROOT)}:{n}"
        for folder in PRODUCT
        for path in sorted((ROOT / folder).rglob("*.py"))
        for n, line in enumerate(path.read_text().splitlines(), start=1)
        if "fmt: skip" in line
    ]
    assert skips == []


def test_the_suites_longest_first_list_names_its_files() -> None:
    from tests.conftest import LONGEST_FIRST

    assert [p for p in LONGEST_FIRST if not (ROOT / p).is_file()] == []
    assert len(set(LONGEST_FIRST)) == len(LONGEST_FIRST)
