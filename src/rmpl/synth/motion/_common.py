"""What every motion reader shares: the :class:`Motion` a reader returns, length units
and axes, and the file-reading helpers that name the line of a bad value."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError

Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

#: Metres per file length unit, for files that do not say ("cmu" is the CMU ASF unit).
LENGTH_UNITS: dict[str, float] = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "inch": 0.0254,
    "cmu": 0.0254 / 0.45,
}
#: Typical vertical extent of a rest pose (soles/toes to head top or eyes), metres.
TYPICAL_REST_HEIGHT = 1.6
#: Rest-pose vertical extents accepted as a human, metres.
PLAUSIBLE_REST_HEIGHT = (1.0, 2.3)


@dataclass(frozen=True, eq=False)
class Motion:
    """Joint trajectories of one clip, metres, z up.

    Attributes:
        names: joint names, length J.
        parents: index of each joint's parent joint, -1 for the root, length J.
        positions: joint positions, metres, shape (T, J, 3).
        rotations: rest-relative global segment rotations, shape (T, J, 3, 3).
        rest: rest pose (every rotation identity, root at the origin), metres, shape (J, 3).
        fps: frames per second.
        source: the file the motion came from.
        scale: metres per file length unit.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    positions: np.ndarray
    rotations: np.ndarray
    rest: np.ndarray
    fps: float
    source: str
    scale: float

    @property
    def num_frames(self) -> int:
        return self.positions.shape[0]

    def index(self, name: str) -> int:
        """Index of the joint called ``name``."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"{self.source}: no joint {name!r}") from None


_Line = tuple[int, list[str]]  # (1-based line number, tokens)


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise InputError(path, None, "a readable file", e.strerror) from None


def _float(path: Path, line: int, field: str, token: str) -> float:
    try:
        value = float(token)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise InputError(path, f"line {line}: {field}", "a finite number", repr(token))
    return value


def _floats(path: Path, line: _Line, count: int, field: str) -> np.ndarray:
    ln, toks = line
    if len(toks) - 1 < count:
        raise InputError(
            path, f"line {ln}: {field}", f"{count} numbers", " ".join(toks[1:]) or "none"
        )
    return np.array([_float(path, ln, field, t) for t in toks[1 : count + 1]])
