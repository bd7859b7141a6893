"""Compare two folders of saved outputs (before / after a refactor), file by file.

``python tests/compare_outputs.py OLD NEW`` walks OLD and NEW: ``.npz`` files must hold the
same arrays (bit for bit, NaN equal to NaN), every other file the same bytes once OLD's and
NEW's own paths are replaced by a placeholder (tables and reports quote their command).
Logs (``*.err``) are compared with progress bars left out, and reported apart. Exit status
0 when everything matches, 1 otherwise.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

#: The marks of a progress line (tqdm) and of a one-off note (matplotlib's font cache).
_PROGRESS = (b"%|", b"/s]", b"s/it]", b"generated new fontManager")


def _npz_differences(a: Path, b: Path) -> list[str]:
    with np.load(a, allow_pickle=False) as x, np.load(b, allow_pickle=False) as y:
        if sorted(x.files) != sorted(y.files):
            return [f"keys {sorted(x.files)} != {sorted(y.files)}"]
        out = []
        for k in x.files:
            u, v = x[k], y[k]
            same = u.shape == v.shape and u.dtype == v.dtype
            if same and u.dtype.kind in "fc":
                same = np.array_equal(u, v, equal_nan=True)
            elif same:
                same = np.array_equal(u, v)
            if not same:
                out.append(f"array {k!r} differs")
        return out


def _text(path: Path, root: Path, log: bool) -> bytes:
    data = path.read_bytes().replace(str(root).encode(), b"<OUT>")
    if log:
        data = b"\n".join(
            line
            for line in re.split(rb"[\r\n]+", data)
            if line.strip() and not any(m in line for m in _PROGRESS)
        )
    return data


def compare(old: Path, new: Path) -> tuple[list[str], list[str]]:
    """(differences in outputs, differences in logs)."""
    outputs, logs = [], []
    names = {p.relative_to(old) for p in old.rglob("*") if p.is_file()}
    names |= {p.relative_to(new) for p in new.rglob("*") if p.is_file()}
    for rel in sorted(names):
        a, b = old / rel, new / rel
        log = rel.suffix == ".err"
        where = logs if log else outputs
        if not (a.is_file() and b.is_file()):
            where.append(f"{rel}: only in {'old' if a.is_file() else 'new'}")
        elif rel.suffix == ".npz":
            where += [f"{rel}: {d}" for d in _npz_differences(a, b)]
        elif _text(a, old, log) != _text(b, new, log):
            where.append(f"{rel}: contents differ")
    return outputs, logs


def main(argv: list[str] | None = None) -> int:
    old, new = (Path(p) for p in (argv or sys.argv[1:]))
    outputs, logs = compare(old, new)
    n = sum(1 for p in old.rglob("*") if p.is_file())
    print(f"{n} files in {old}; outputs differing: {len(outputs)}; logs differing: {len(logs)}")
    for line in outputs + logs:
        print("  " + line)
    return 1 if outputs else 0


if __name__ == "__main__":
    sys.exit(main())
