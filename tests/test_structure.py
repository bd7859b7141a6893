"""The package's shape: no import circles, nothing imported upwards, the size limits.

Run as a script for the figures: ``python tests/test_structure.py`` prints the circles,
the upward imports, the long functions and the long modules.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "rmpl"

#: Layers, lowest first: a module may import its own layer or a lower one, never a higher
#: one. A module's layer is that of its longest listed prefix.
LAYERS = [
    ["rmpl.errors", "rmpl.skeleton", "rmpl.metrics", "rmpl.anthropometry", "rmpl.filters",
     "rmpl.io", "rmpl.geometry"],
    ["rmpl.model", "rmpl.synth"],
    ["rmpl.data"],
    ["rmpl.inference", "rmpl.inference_temporal", "rmpl.training", "rmpl.models"],
    ["rmpl.pipeline", "rmpl.viz"],
    ["rmpl.evaluate", "rmpl.bench", "rmpl.synth.generate"],
    ["rmpl.cli", "rmpl.benchmarks", "rmpl"],
]  # fmt: skip

#: The issue's limits: functions over 60 lines (at most this many), over 100 (none);
#: modules over 1000 lines; CLI modules over 200.
MAX_LONG_FUNCTIONS, LONG, TOO_LONG = 10, 60, 100
MAX_MODULE, MAX_CLI_MODULE = 1000, 200


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imported(node: ast.AST, here: str, is_package: bool, known: set[str]) -> list[str]:
    """The rmpl modules one import statement names (anywhere: top level or in a function)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name in known]
    if not isinstance(node, ast.ImportFrom):
        return []
    base = node.module or ""
    if node.level:  # relative import
        parts = here.split(".")
        if not is_package:
            parts = parts[:-1]
        parts = parts[: len(parts) - node.level + 1]
        base = ".".join(parts + ([base] if base else []))
    names = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in known]
    if len(names) == len(node.names):
        return names
    return names + ([base] if base in known else [])


def import_graph() -> dict[str, set[str]]:
    """Module -> the rmpl modules it imports (a package's ``__init__`` counts only when
    it is named itself)."""
    mods = modules()
    known = set(mods)
    graph = {}
    for name, path in mods.items():
        tree = ast.parse(path.read_text(), str(path))
        is_package = path.name == "__init__.py"
        found = set()
        for node in ast.walk(tree):
            found.update(_imported(node, name, is_package, known))
        found.discard(name)
        graph[name] = found
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def layer(name: str) -> int:
    best, level = -1, len(LAYERS) - 1
    for i, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if (name == p or name.startswith(p + ".")) and len(p) > best:
                best, level = len(p), i
    return level


def upward(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(importer, imported) pairs where the imported module sits in a higher layer."""
    return sorted((a, b) for a, bs in graph.items() for b in bs if layer(b) > layer(a))


def functions() -> list[tuple[int, str]]:
    """(lines, "module:function") of every function and method, decorators excluded."""
    out = []
    for name, path in modules().items():
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                out.append((node.end_lineno - node.lineno + 1, f"{name}:{node.name}"))
    return sorted(out, reverse=True)


def module_lines() -> list[tuple[int, str]]:
    return sorted(
        ((len(p.read_text().splitlines()), n) for n, p in modules().items()), reverse=True
    )


def test_no_import_circles():
    assert cycles(import_graph()) == []


def test_nothing_imported_upwards():
    assert upward(import_graph()) == []


def test_function_sizes():
    sizes = functions()
    assert [f for n, f in sizes if n > TOO_LONG] == []
    long = [f for n, f in sizes if n > LONG]
    assert len(long) <= MAX_LONG_FUNCTIONS, long


def test_module_sizes():
    lines = module_lines()
    assert [m for n, m in lines if n > MAX_MODULE] == []
    assert [m for n, m in lines if m.startswith("rmpl.cli.") and n > MAX_CLI_MODULE] == []


def test_the_tools_see_a_circle_and_an_upward_import():
    graph = {"rmpl.data.a": {"rmpl.pipeline.b"}, "rmpl.pipeline.b": {"rmpl.data.a"}}
    assert cycles(graph) == [["rmpl.data.a", "rmpl.pipeline.b"]]
    assert upward(graph) == [("rmpl.data.a", "rmpl.pipeline.b")]


def main() -> int:
    graph = import_graph()
    circles, up = cycles(graph), upward(graph)
    print(f"{len(graph)} modules, {sum(map(len, graph.values()))} imports")
    print(f"import circles: {len(circles)}")
    for c in circles:
        print("  " + " <-> ".join(c))
    print(f"upward imports: {len(up)}")
    for a, b in up:
        print(f"  {a} -> {b}")
    sizes = functions()
    print(f"functions over {LONG} lines: {sum(n > LONG for n, _ in sizes)}, "
          f"over {TOO_LONG}: {sum(n > TOO_LONG for n, _ in sizes)}")  # fmt: skip
    for n, f in sizes:
        if n > LONG:
            print(f"  {n:4d} {f}")
    print("modules over 1000 lines / CLI modules over 200:")
    for n, m in module_lines():
        if n > MAX_MODULE or (m.startswith("rmpl.cli.") and n > MAX_CLI_MODULE):
            print(f"  {n:5d} {m}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
