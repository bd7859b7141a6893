"""The measurements behind docs/results.md: one module per benchmark, one entry point.

Each module ``rmpl.benchmarks.<name>`` has a docstring (its first line says what it
measures, the rest how to run it) and ``main(argv: list[str] | None = None) -> int``. Run
one as ``rmpl benchmark NAME [args]`` or ``python -m rmpl.benchmarks.NAME [args]``;
``rmpl benchmark`` alone lists them. Modules whose name starts with ``_`` hold shared code.

>>> "foot_eval" in available()
True
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import pkgutil

__all__ = ["available", "run"]


def _summary(name: str) -> str:
    """The first line of a benchmark module's docstring, read without importing it."""
    spec = importlib.util.find_spec(f"{__name__}.{name}")
    if spec is None or spec.origin is None:
        return ""
    with open(spec.origin, encoding="utf-8") as f:
        doc = ast.get_docstring(ast.parse(f.read()))
    return doc.strip().splitlines()[0] if doc else ""


def available() -> dict[str, str]:
    """Every benchmark module of the package: name -> the first line of its docstring."""
    names = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
    return {name: _summary(name) for name in names}


def run(name: str, argv: list[str] | None = None) -> int:
    """Run benchmark ``name`` with command-line arguments ``argv``; returns its exit code."""
    from rmpl.errors import InputError

    names = available()
    if name not in names:
        raise InputError(None, "NAME", f"a benchmark: one of {', '.join(names)}", name)
    module = importlib.import_module(f"{__name__}.{name}")
    return int(module.main(list(argv or [])) or 0)
