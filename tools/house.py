"""The house's size rules, for what ruff has no rule for: a product file at
most 400 lines, a function at most 60, a class at most 20 attributes, a test
file at most 600 lines. Prints each breach as ``path: what``; exit 1 if any.

    python tools/house.py [PATH ...]   (default: the product and the tests)
    python tools/house.py --largest N  the N largest product files, functions and classes
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PRODUCT = ("swarm", "agents", "world", "protocol")
MAX_FILE, MAX_TEST_FILE, MAX_FUNCTION, MAX_ATTRIBUTES = 400, 600, 60, 20


def attributes(cls: ast.ClassDef) -> set[str]:
    """Names a class's instances hold: its annotated fields and every ``self.x =``."""
    names = {n.target.id for n in cls.body if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)}
    for node in ast.walk(cls):
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        for t in targets:
            if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) and t.value.id == "self":
                names.add(t.attr)
    return names


def breaches(path: Path, root: Path = ROOT) -> Iterator[str]:
    rel = path.resolve().relative_to(root.resolve())
    text = path.read_text()
    lines = text.count("\n")
    is_test = rel.parts[0] == "tests"
    limit = MAX_TEST_FILE if is_test else MAX_FILE
    if lines > limit:
        yield f"{rel}: {lines} lines (at most {limit})"
    if is_test:
        return
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            n = node.end_lineno - node.lineno + 1
            if n > MAX_FUNCTION:
                yield f"{rel}:{node.lineno}: function {node.name} is {n} lines (at most {MAX_FUNCTION})"
        elif isinstance(node, ast.ClassDef):
            n = len(attributes(node))
            if n > MAX_ATTRIBUTES:
                yield f"{rel}:{node.lineno}: class {node.name} holds {n} attributes (at most {MAX_ATTRIBUTES})"


def files(paths: list[str]) -> list[Path]:
    roots = [Path(p) for p in paths] or [ROOT / d for d in (*PRODUCT, "tests")]
    return sorted(f for r in roots for f in ([r] if r.is_file() else r.rglob("*.py")))


def largest(n: int) -> str:
    """The ``n`` largest product files (lines), functions (lines) and classes (attributes)."""
    sizes: dict[str, list[tuple[int, str]]] = {"files": [], "functions": [], "classes": []}
    for path in files([str(ROOT / d) for d in PRODUCT]):
        rel, text = path.relative_to(ROOT), path.read_text()
        sizes["files"].append((text.count("\n"), f"{rel}"))
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                sizes["functions"].append((node.end_lineno - node.lineno + 1, f"{rel}:{node.lineno} {node.name}"))
            elif isinstance(node, ast.ClassDef):
                sizes["classes"].append((len(attributes(node)), f"{rel}:{node.lineno} {node.name}"))
    limits = {"files": MAX_FILE, "functions": MAX_FUNCTION, "classes": MAX_ATTRIBUTES}
    out = []
    for what, found in sizes.items():
        out.append(f"largest {what} (at most {limits[what]}):")
        out += [f"  {size:4d}  {name}" for size, name in sorted(found, reverse=True)[:n]]
    return "\n".join(out)


def main(argv: list[str]) -> int:
    if argv[:1] == ["--largest"]:
        print(largest(int(argv[1]) if len(argv) > 1 else 3))
        return 0
    found = [b for f in files(argv) for b in breaches(f)]
    print("\n".join(found) or "no breaches")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
