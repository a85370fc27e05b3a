"""docs/controllers.md's engine example passes as a user's tests, in this
process (no process started): its complete controller written as
``my_controller.py`` on the Python path, then each test of the page's
"Testing it in one process" block called."""

from __future__ import annotations

import re
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.helpers import ROOT

TEXT = (ROOT / "docs" / "controllers.md").read_text()
BLOCKS = re.findall(r"^```python\n(.*?)^```$", TEXT, re.M | re.S)
ENGINE = next(b for b in BLOCKS if "import Engine" in b)


@pytest.fixture
def my_controller(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    (tmp_path / "my_controller.py").write_text(BLOCKS[0])
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    sys.modules.pop("my_controller", None)


def _tests() -> list[str]:
    return re.findall(r"^def (test_\w+)\(\):", ENGINE, re.M)


def test_the_page_has_its_engine_tests() -> None:
    assert _tests() == [
        "test_it_holds_fig11_through_an_agent_restart",
        "test_it_trails_its_slot_tick_by_tick_and_a_reset_flies_it_again",
    ]
    assert "formation_swarm." not in ENGINE  # public names only


@pytest.mark.parametrize("name", _tests())
@pytest.mark.usefixtures("my_controller")
def test_the_pages_engine_test_passes(name: str) -> None:
    namespace: dict[str, object] = {"__name__": "test_engine"}
    exec(compile(ENGINE, "controllers.md", "exec"), namespace)  # the page's own code
    started = time.process_time()
    namespace[name]()  # type: ignore[operator]
    assert time.process_time() - started < 2.0  # CPU: the wall clock of a loaded machine says little
