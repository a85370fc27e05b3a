"""A script that starts a Launch without ``if __name__ == "__main__":`` is
refused in one line, before anything starts: which main scripts
multiprocessing's children import again, which have the guard, and the
check run from a script's top-level code (tests/system/test_main_guard.py
runs such scripts)."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import pytest

from formation_swarm.launch import mainguard

UNGUARDED = "from formation_swarm.launch import mainguard\nmainguard.check()\n"
GUARDED = "from formation_swarm.launch import mainguard\nif __name__ == '__main__':\n    mainguard.check()\n"


@pytest.mark.parametrize(
    ("source", "guarded"),
    [
        (GUARDED, True),
        ('if "__main__" == __name__:\n    pass\n', True),
        ("import sys\nif __name__ == '__main__':\n    sys.exit(0)\n", True),
        (UNGUARDED, False),
        ("def main():\n    if __name__ == '__main__':\n        pass\n", False),  # not at the top level
        ("if __name__ != '__main__':\n    pass\n", False),
        ("if __name__ == '__mp_main__':\n    pass\n", False),
        ("x = 1 +\n", True),  # unreadable: nothing claimed
    ],
)
def test_a_top_level_main_test_is_the_guard(tmp_path: Path, source: str, guarded: bool) -> None:
    path = tmp_path / "script.py"
    path.write_text(source)
    assert mainguard.has_guard(str(path)) is guarded


def _module(name: str, spec_name: str | None = None, file: str | None = None) -> types.ModuleType:
    mod = types.ModuleType(name)
    if spec_name is not None:
        mod.__spec__ = types.SimpleNamespace(name=spec_name, origin=f"/src/{spec_name.replace('.', '/')}.py")  # type: ignore[assignment]
    else:
        mod.__spec__ = None
    if file is not None:
        mod.__file__ = file
    return mod


def test_the_scripts_multiprocessing_imports_again() -> None:
    assert mainguard.reimported_source(_module("__main__", file="/w/run.py")) == "/w/run.py"  # python run.py
    assert mainguard.reimported_source(_module("__main__", spec_name="tools.run")) == "/src/tools/run.py"  # -m
    assert mainguard.reimported_source(_module("__main__", spec_name="formation_swarm.cli.__main__")) is None
    assert mainguard.reimported_source(_module("__main__")) is None  # python -c, a REPL
    assert mainguard.reimported_source(_module("__main__", file="/usr/bin/ipython")) is None
    assert mainguard.reimported_source(None) is None


def _run_as_main(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Run ``path``'s top-level code as ``python path`` would, in this process."""
    main = _module("__main__", file=str(path))
    monkeypatch.setitem(sys.modules, "__main__", main)
    exec(compile(path.read_text(), str(path), "exec"), vars(main))  # noqa: S102 - the test's own script


def test_an_unguarded_script_is_refused_in_one_line_naming_the_fix(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "unguarded.py"
    path.write_text(UNGUARDED)
    with pytest.raises(mainguard.MainGuardError) as err:
        _run_as_main(path, monkeypatch)
    said = str(err.value)
    assert said == mainguard.message(str(path))
    assert "\n" not in said
    assert said.startswith(f"{path} starts a Launch when it is imported")
    assert said.endswith('put the code that starts the run under `if __name__ == "__main__":`')


def test_a_guarded_script_and_a_call_from_outside_the_top_level_pass(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "guarded.py"
    path.write_text(GUARDED)
    _run_as_main(path, monkeypatch)  # its main test is true here: check() ran and passed
    unguarded = tmp_path / "unguarded.py"
    unguarded.write_text(UNGUARDED)
    monkeypatch.setitem(sys.modules, "__main__", _module("__main__", file=str(unguarded)))
    mainguard.check()  # not from the script's top-level code: a function it did not call as it ran


def test_a_child_importing_the_script_again_leaves_with_the_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import multiprocessing

    path = tmp_path / "guarded.py"
    path.write_text(GUARDED)
    monkeypatch.setitem(sys.modules, "__main__", _module("__main__", file=str(path)))
    monkeypatch.setattr(multiprocessing.current_process(), "_inheriting", True, raising=False)
    with pytest.raises(SystemExit) as left:
        mainguard.check()
    assert left.value.code == mainguard.message(str(path))  # printed alone on stderr, exit status 1
