"""What several benchmarks share: a rig from a data set's camera arrays, the entry point."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig


def set_rig(d: dict[str, np.ndarray], m: int, views: Sequence[int], prefix: str = "") -> Rig:
    """Cameras ``views`` of item ``m`` (a mesh, scene or sequence) of a data set's arrays.

    ``d`` holds ``K`` (M, V, 3, 3), ``R`` (M, V, 3, 3), ``t`` (M, V, 3) and, when known,
    ``size`` (M, V, 2) pixels; camera ``v`` is named ``f"{prefix}{v}"``.
    """
    return Rig(
        tuple(
            Camera(
                d["K"][m, v],
                d["R"][m, v],
                d["t"][m, v],
                size=tuple(int(x) for x in d["size"][m, v]) if "size" in d else None,
                name=f"{prefix}{v}",
            )
            for v in views
        )
    )


def run_main(main: Callable[[list[str]], int]) -> int:
    """``python -m rmpl.benchmarks.NAME``: a user's mistake is one line on stderr, exit 2."""
    try:
        return main(sys.argv[1:])
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


def run_commands(commands: Sequence[Sequence[str]], dry_run: bool = False) -> int:
    """Run ``rmpl`` commands in order (``["train", CONFIG, ...]``), each printed first.

    Stops at the first that fails and returns its exit code; ``dry_run`` only prints them.
    Every ``rmpl train`` and ``rmpl generate`` resumes its output folder, so a killed
    sequence continues where it stopped when run again.
    """
    import shlex

    from rmpl.cli import main as rmpl

    for command in commands:
        print("rmpl " + shlex.join(command), flush=True)
        if not dry_run and (code := rmpl(list(command))) != 0:
            return code
    return 0


def toml_string(text: str | Path) -> str:
    """``text`` as a TOML string for ``--set key=VALUE``: ``bank.npz`` -> ``"bank.npz"``."""
    return '"' + str(text) + '"'


def emit_json(doc: dict, path: str | Path | None) -> None:
    """Print a benchmark's figures as JSON, and write them to ``path`` when given."""
    import json

    text = json.dumps(doc, indent=1)
    print(text)
    if path:
        Path(path).write_text(text + "\n", encoding="utf-8")
