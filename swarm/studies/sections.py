"""The generated sections of the docs: the markers a table or a text made by
``swarm results`` sits between (in docs/results.md and README.md), and
writing it there.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Sequence
from pathlib import Path


def markers(what: str = "results table", settings: str = "") -> tuple[str, str]:
    """The markers a generated table sits between, naming its settings if any."""
    name = f"{what} ({settings})" if settings else what
    return f"<!-- {name}: begin -->", f"<!-- {name}: end -->"


BEGIN, END = markers()


def check_markers(path: Path, begin: str = BEGIN, end: str = END) -> None:
    """Raise ValueError unless ``path`` is a file with the table's markers."""
    try:
        doc = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"--write {path}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
    if begin not in doc or end not in doc:
        raise ValueError(f"--write {path}: has no {begin} ... {end} markers")


def write_into(path: Path, text: str, begin: str = BEGIN, end: str = END) -> None:
    check_markers(path, begin, end)
    doc = path.read_text()
    new = re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda _m: f"{begin}\n{text}\n{end}", doc, flags=re.S)
    path.write_text(new)


def write_all(writes: Sequence[Path], text: str, begin: str, end: str) -> bool:
    """``text`` between the markers of every file; False, having said why, if one cannot take it."""
    for target in writes:
        try:
            write_into(target, text, begin, end)
        except (OSError, ValueError) as exc:
            print(f"swarm results: {exc}", file=sys.stderr)
            return False
    return True
