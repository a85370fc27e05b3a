"""A script that starts a ``Launch`` must do it under ``if __name__ == "__main__":``.

The launcher starts its processes from multiprocessing's fork server, and
multiprocessing has a child import the parent's main script again (as
``__mp_main__``) so that what it defines can be unpickled. A script that
starts a run when imported would start one in that child: multiprocessing
stops it there with a traceback about the "bootstrapping phase". Here the
launcher says so in one line before anything starts, and a child that
imports such a script anyway leaves with that line instead of the traceback.
"""

from __future__ import annotations

import ast
import multiprocessing
import os
import sys
from types import ModuleType

GUARD = 'if __name__ == "__main__":'


class MainGuardError(RuntimeError):
    """The main script starts a Launch as it is imported."""


def message(path: str) -> str:
    return (
        f"{path} starts a Launch when it is imported, and multiprocessing's fork server imports the main "
        f"script again in the processes it starts: put the code that starts the run under `{GUARD}`"
    )


def check() -> None:
    """Raise MainGuardError (in a child importing the script again: SystemExit)
    with one line naming the fix when the main script, which multiprocessing's
    children import again, starts a Launch from its top-level code without
    the guard."""
    main = sys.modules.get("__main__")
    path = reimported_source(main)
    if main is None or path is None:
        return
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        raise SystemExit(message(path))  # one line on stderr, no traceback
    if _in_top_level_code(main) and not has_guard(path):
        raise MainGuardError(message(path))


def reimported_source(main: ModuleType | None) -> str | None:
    """The file of ``__main__`` that multiprocessing's children import again,
    or None when they do not (``python -c``, a package's ``__main__``, a REPL):
    the rules of ``multiprocessing.spawn.get_preparation_data``."""
    if main is None:
        return None
    spec = getattr(main, "__spec__", None)
    name = getattr(spec, "name", None)
    if name is not None:
        if name == "__main__" or name.endswith(".__main__"):
            return None
        return getattr(spec, "origin", None)
    path = getattr(main, "__file__", None)
    if not isinstance(path, str) or os.path.splitext(os.path.basename(path))[0] == "ipython":
        return None
    return path


def has_guard(path: str) -> bool:
    """Whether the module at ``path`` has a top-level ``if __name__ == "__main__":``
    (True when it cannot be read: then nothing is claimed)."""
    try:
        with open(path, "rb") as f:
            tree = ast.parse(f.read(), filename=path)
    except (OSError, SyntaxError, ValueError):
        return True
    return any(isinstance(node, ast.If) and _is_main_test(node.test) for node in tree.body)


def _is_main_test(test: ast.expr) -> bool:
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1 and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = (test.left, test.comparators[0])
    names = [s for s in sides if isinstance(s, ast.Name) and s.id == "__name__"]
    mains = [s for s in sides if isinstance(s, ast.Constant) and s.value == "__main__"]
    return len(names) == len(mains) == 1


def _in_top_level_code(main: ModuleType) -> bool:
    """Whether the main script's top-level code is on the stack (a Launch started
    from a function the script calls as it runs counts too)."""
    frame = sys._getframe(1)
    while frame is not None:
        if frame.f_code.co_name == "<module>" and frame.f_globals is vars(main):
            return True
        frame = frame.f_back
    return False
