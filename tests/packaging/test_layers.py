"""Imports point one way: the contracts of pyproject.toml hold on every module
of formation_swarm (tools/lint_imports.py), a planted upward import breaks
them, and the maths and the wire load no Zenoh when they run."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

from tests.helpers import ROOT

sys.path.insert(0, str(ROOT / "tools"))
import lint_imports  # noqa: E402

CONTRACTS = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
LAYERS = [name.strip() for layer in CONTRACTS[0]["layers"] for name in layer.split("|")]


def _lint(tree: Path) -> subprocess.CompletedProcess[str]:
    lint = Path(sys.executable).with_name("lint-imports")
    env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONDONTWRITEBYTECODE": "1"}
    argv = [str(lint), str(ROOT / "pyproject.toml"), "--no-cache"]
    return subprocess.run(argv, cwd=tree, env=env, capture_output=True, text=True, timeout=120)


def test_the_contracts_hold() -> None:
    res = subprocess.run([sys.executable, str(ROOT / "tools" / "lint_imports.py")], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    assert f"Contracts: {len(CONTRACTS)} kept, 0 broken." in res.stdout


def test_every_module_is_in_a_layer(tmp_path: Path) -> None:
    lint_imports.lay_out(tmp_path)
    modules = [
        ".".join(p.relative_to(tmp_path).with_suffix("").parts).removesuffix(".__init__")
        for p in (tmp_path / "formation_swarm").rglob("*.py")
    ]
    assert len(modules) > 70

    def layered(m: str) -> bool:
        return any(m == layer or m.startswith(layer + ".") for layer in LAYERS)

    assert [m for m in modules if m != "formation_swarm" and not layered(m)] == []


def test_a_planted_upward_import_breaks_them(tmp_path: Path) -> None:
    lint_imports.lay_out(tmp_path)
    fuzzy = tmp_path / "formation_swarm" / "agents" / "fuzzy.py"
    fuzzy.write_text(fuzzy.read_text() + "\nfrom formation_swarm.launch import launcher  # noqa: E402, F401\n")
    res = _lint(tmp_path)
    assert res.returncode == 1
    assert "Layers: every arrow downward BROKEN" in res.stdout
    assert "formation_swarm.agents.fuzzy -> formation_swarm.launch.launcher" in res.stdout


def test_a_planted_import_of_another_process_breaks_them(tmp_path: Path) -> None:
    lint_imports.lay_out(tmp_path)
    wire = tmp_path / "formation_swarm" / "nodes" / "agent" / "wire.py"
    wire.write_text(wire.read_text() + "\nfrom formation_swarm.nodes.logger import ledger  # noqa: E402, F401\n")
    res = _lint(tmp_path)
    assert res.returncode == 1
    assert "formation_swarm.nodes.agent.wire -> formation_swarm.nodes.logger.ledger" in res.stdout


def test_no_import_loop_even_through_imports_inside_functions(tmp_path: Path) -> None:
    lint_imports.lay_out(tmp_path)
    graph = import_graph(tmp_path)
    assert len(graph) > 150
    assert import_loops(graph) == []


def test_a_loop_through_a_relative_import_inside_a_function_is_found(tmp_path: Path) -> None:
    lint_imports.lay_out(tmp_path)
    ekf = tmp_path / "formation_swarm" / "agents" / "ekf.py"
    ekf.write_text(ekf.read_text() + "\n\ndef _late():\n    from . import tracking  # noqa: F401\n")
    loops = import_loops(import_graph(tmp_path))
    assert [loop for loop in loops if "formation_swarm.agents.ekf" in loop] != []
    assert "formation_swarm.agents.tracking" in next(loop for loop in loops if "formation_swarm.agents.ekf" in loop)


def test_the_loop_finder_finds_a_loop_made_inside_a_function() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": set(), "d": {"d"}}
    assert import_loops(graph) == []
    graph["c"] = {"a"}
    assert import_loops(graph) == [["a", "b", "c"]]


def import_graph(tree: Path) -> dict[str, set[str]]:
    """Every module of formation_swarm -> the package's modules it imports,
    wherever in the file (a function's body too); not those under
    ``if TYPE_CHECKING:``, which never run."""
    files = {
        ".".join(p.relative_to(tree).with_suffix("").parts).removesuffix(".__init__"): p
        for p in (tree / "formation_swarm").rglob("*.py")
    }
    graph: dict[str, set[str]] = {}
    for module, path in files.items():
        tree_ = ast.parse(path.read_text())
        skip = {
            id(n)
            for node in ast.walk(tree_)
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
            for stmt in node.body
            for n in ast.walk(stmt)
        }
        out: set[str] = set()
        for node in ast.walk(tree_):
            if id(node) in skip:
                continue
            if isinstance(node, ast.Import):
                out |= {a.name for a in node.names if a.name in files}
            elif isinstance(node, ast.ImportFrom):
                source = _absolute(node, module, is_package=path.name == "__init__.py")
                for a in node.names:
                    sub = f"{source}.{a.name}"
                    out.add(sub if sub in files else source)
        graph[module] = {m for m in out if m in files and m != module}
    return graph


def _absolute(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The module ``from X import ...`` names, ``from . import`` and ``from ..x import`` too."""
    if node.level == 0:
        return node.module or ""
    package = module if is_package else module.rsplit(".", 1)[0]
    for _ in range(node.level - 1):
        package = package.rsplit(".", 1)[0]
    return f"{package}.{node.module}" if node.module else package


def import_loops(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    loops: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                loops.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(loops)


def test_a_planted_zenoh_import_in_the_maths_breaks_them(tmp_path: Path) -> None:
    lint_imports.lay_out(tmp_path)
    ekf = tmp_path / "formation_swarm" / "agents" / "ekf.py"
    ekf.write_text(ekf.read_text() + "\nimport zenoh  # noqa: E402, F401\n")
    res = _lint(tmp_path)
    assert res.returncode == 1
    assert "formation_swarm.agents.ekf -> zenoh" in res.stdout


def test_the_maths_and_the_wire_load_no_zenoh_when_they_run() -> None:
    pure = [
        "formation_swarm.agents.follower",
        "formation_swarm.agents.pilot",
        "formation_swarm.world.engine",
        "formation_swarm.world.process_faults",
        "formation_swarm.protocol.messages",
        "formation_swarm.protocol.links",
        "formation_swarm.spec.scenario",
    ]
    code = "import importlib, json, sys\n"
    code += "".join(f"importlib.import_module({m!r})\n" for m in pure)
    code += "print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60)
    loaded = set(json.loads(out.stdout))
    assert not {m for m in loaded if m.split(".")[0] in ("zenoh", "rerun")}
    assert not {m for m in loaded if m.startswith(("formation_swarm.launch", "formation_swarm.nodes"))}
    # and the package's own folders are not importable under their folder names
    assert not loaded & {"agents", "world", "protocol", "swarm"}
