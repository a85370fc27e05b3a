"""The house's size rules hold: tools/house.py finds no file, function or
class over its bound, no `# fmt: skip` lays out the product by hand, and few
tests compare a whole sentence."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

from tests.helpers import ROOT

PRODUCT = ("swarm", "agents", "world", "protocol")
MAX_SENTENCE_ASSERTS = 60  # in the whole of tests/


def test_no_file_function_or_class_is_over_its_bound() -> None:
    res = subprocess.run([sys.executable, str(ROOT / "tools" / "house.py")], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout
    assert res.stdout.strip() == "no breaches"


def test_a_long_function_is_a_breach(tmp_path: Path) -> None:
    long = tmp_path / "long.py"
    long.write_text("def f():\n" + "    x = 1\n" * 61)
    sys.path.insert(0, str(ROOT / "tools"))
    import house

    (found,) = house.breaches(long, root=tmp_path)
    assert found.startswith("long.py:1: function f ")
    assert re.findall(r"\d+", found.removeprefix("long.py:1:")) == ["62", "60"]  # its length, the bound


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


def _words(node: ast.expr) -> int:
    """The words of a string literal or f-string: its tokens with a letter or
    digit in them, each ``{placeholder}`` one; 0 for anything else."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        text = node.value
    elif isinstance(node, ast.JoinedStr):
        text = "".join(v.value if isinstance(v, ast.Constant) else "X" for v in node.values)
    else:
        return 0
    return sum(any(c.isalnum() for c in token) for token in text.split())


def _is_sentence(node: ast.expr) -> bool:
    if isinstance(node, ast.List | ast.Tuple):
        return any(_is_sentence(e) for e in node.elts)
    return _words(node) >= 3


def sentence_asserts(source: str) -> list[int]:
    """The lines of the asserts that compare a whole sentence: an ``assert``
    whose test is a comparison with ``==`` or ``!=`` one side of which is a
    string literal or f-string of 3 or more words (``_words``), or a list or
    tuple literal holding one. Such an assert breaks when the sentence is
    reworded, though it means its numbers: a test asserts the record behind
    the sentence, and one test per sentence shape checks the words."""
    return [
        node.lineno
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Assert)
        and isinstance(node.test, ast.Compare)
        and any(isinstance(op, ast.Eq | ast.NotEq) for op in node.test.ops)
        and any(_is_sentence(side) for side in (node.test.left, *node.test.comparators))
    ]


def test_few_asserts_compare_a_whole_sentence() -> None:
    """At most 60 asserts in the whole of tests/ compare a whole sentence: an
    ``assert`` whose test is a comparison with ``==`` or ``!=`` one side of
    which is a string literal or f-string of 3 or more words (a word: a
    whitespace-separated token with a letter or digit in it, each
    ``{placeholder}`` one), or a list or tuple literal holding one
    (``sentence_asserts``, read from each file's syntax tree). The others
    assert the record behind a sentence, or its numbers and names."""
    counts = {
        str(path.relative_to(ROOT)): n
        for path in sorted((ROOT / "tests").rglob("*.py"))
        if (n := len(sentence_asserts(path.read_text())))
    }
    listing = "\n".join(f"{n:4} {path}" for path, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))
    total = sum(counts.values())
    assert total <= MAX_SENTENCE_ASSERTS, f"{total} asserts compare a whole sentence:\n{listing}"


def test_the_sentence_counter_counts_a_planted_example() -> None:
    """It counts a sentence, an f-string one and one in a list; not two words
    (in a tuple too), a sentence tested with ``in``, punctuation between
    placeholders, or an assert that is no comparison."""
    planted = """
def test_planted():
    assert said() == "holds in 10/10 seeds"
    assert said() != f"robot {rid} lost its agent"
    assert said() == ["ok", "two robots touch"]
    assert (said(), 2) == ("two words", 2)
    assert "holds in 10/10 seeds" in said()
    assert said() == f"  - {axis}: {band}."
    assert said() == "1.5 ± 0.2 [3.0]" or True
    assert n == 3
"""
    assert sentence_asserts(planted) == [3, 4, 5]


def test_mutation_testing_names_modules_and_test_files_that_exist() -> None:
    """tools/mutate.py finds each test file it names by its name alone (it stops
    at import when two share one) and mutates modules that exist."""
    res = subprocess.run([sys.executable, str(ROOT / "tools" / "mutate.py"), "--help"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    sys.path.insert(0, str(ROOT / "tools"))
    import mutate

    assert [m.path for m in mutate.MODULES if not (ROOT / m.path).is_file()] == []
    assert [t for m in mutate.MODULES for t in m.tests if not (ROOT / t.split("::")[0]).is_file()] == []
