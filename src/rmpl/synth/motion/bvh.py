"""BVH motion files: the hierarchy header and the MOTION frames."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.synth.motion._common import (
    Motion,
    _float,
    _read_text,
)
from rmpl.synth.motion.kinematics import (
    _checked_scale,
    _euler,
    _points_z_up,
    _rotations_z_up,
)

_CHANNELS = {
    f"{a}{kind}": f"{a.lower()}{kind[0]}" for a in "XYZ" for kind in ("position", "rotation")
}


@dataclass(frozen=True, eq=False)
class _BvhNode:
    name: str
    parent: int
    offset: np.ndarray  # (3,) file units
    channels: tuple[str, ...]  # "xp" = Xposition, "zr" = Zrotation, ...


class _Tokens:
    """Header tokens with their line numbers."""

    def __init__(self, path: Path, lines: list[str]) -> None:
        self.path = path
        self.items = [(t, n) for n, line in enumerate(lines, 1) for t in line.split()]
        self.pos = 0

    def peek(self) -> str:
        return self.items[self.pos][0] if self.pos < len(self.items) else ""

    def line(self) -> int:
        return self.items[min(self.pos, len(self.items) - 1)][1] if self.items else 1

    def take(self, what: str) -> str:
        """The next token, whatever it is; ``what`` describes it for the error."""
        if self.pos >= len(self.items):
            raise InputError(self.path, f"line {self.line()}", what, "end of file")
        self.pos += 1
        return self.items[self.pos - 1][0]

    def expect(self, word: str) -> None:
        """Consume the keyword ``word`` (any case)."""
        line, tok = self.line(), self.take(repr(word))
        if tok.upper() != word.upper():
            raise InputError(self.path, f"line {line}", repr(word), tok)

    def numbers(self, count: int, field: str) -> np.ndarray:
        return np.array(
            [_float(self.path, self.line(), field, self.take(field)) for _ in range(count)]
        )


def _bvh_joint(tok: _Tokens, name: str, parent: int, nodes: list[_BvhNode]) -> None:
    tok.expect("{")
    tok.expect("OFFSET")
    offset = tok.numbers(3, "OFFSET")
    index = len(nodes)
    channels: tuple[str, ...] = ()
    if tok.peek().upper() == "CHANNELS":
        tok.take("CHANNELS")
        line = tok.line()
        n = tok.take("number of channels")
        if not n.isdigit():
            raise InputError(tok.path, f"line {line}: CHANNELS", "a channel count", n)
        names = [tok.take("channel name") for _ in range(int(n))]
        bad = [c for c in names if c not in _CHANNELS]
        if bad or len(set(names)) != len(names):
            raise InputError(
                tok.path,
                f"line {line}: CHANNELS",
                f"{n} distinct channel names such as Xposition, Zrotation",
                " ".join(names),
            )
        channels = tuple(_CHANNELS[c] for c in names)
    nodes.append(_BvhNode(name, parent, offset, channels))
    ends = 0
    while tok.peek() != "}":
        kind = tok.take("JOINT, End Site or }")
        if kind.upper() == "JOINT":
            _bvh_joint(tok, tok.take("joint name"), index, nodes)
        elif kind.upper() == "END":
            tok.expect("Site")
            tok.expect("{")
            tok.expect("OFFSET")
            end_offset = tok.numbers(3, "OFFSET")
            tok.expect("}")
            nodes.append(
                _BvhNode(f"{name}_end" + (f"{ends}" if ends else ""), index, end_offset, ())
            )
            ends += 1
        else:
            raise InputError(tok.path, f"line {tok.line()}", "JOINT, End Site or }", kind)
    tok.expect("}")


def _bvh_header(path: Path, lines: list[str]) -> list[_BvhNode]:
    tok = _Tokens(path, lines)
    tok.expect("HIERARCHY")
    tok.expect("ROOT")
    nodes: list[_BvhNode] = []
    _bvh_joint(tok, tok.take("root name"), -1, nodes)
    if tok.peek():
        raise InputError(path, f"line {tok.line()}", "MOTION after the one ROOT", tok.peek())
    names = [n.name for n in nodes]
    if len(set(names)) != len(names):
        raise InputError(path, "HIERARCHY", "distinct joint names", names)
    return nodes


def _bvh_motion(
    path: Path, lines: list[str], start: int, num_channels: int
) -> tuple[np.ndarray, float]:
    """Parse from the MOTION line (index ``start``): values (T, C) and the frame time."""

    def field(i: int, key: str) -> str:
        text = lines[i].strip() if i < len(lines) else ""
        if not text.lower().startswith(key.lower()):
            raise InputError(path, f"line {i + 1}", f"'{key} ...'", text[:40] or "end of file")
        return text[len(key) :].strip()

    frames_text, dt_text = field(start + 1, "Frames:"), field(start + 2, "Frame Time:")
    if not frames_text.isdigit():
        raise InputError(path, f"line {start + 2}: Frames", "a frame count", frames_text)
    dt = _float(path, start + 3, "Frame Time", dt_text)
    if not dt > 0:
        raise InputError(path, f"line {start + 3}: Frame Time", "a positive number", dt)
    T = int(frames_text)
    rows = [i for i in range(start + 3, len(lines)) if lines[i].strip()]
    if len(rows) != T:
        raise InputError(
            path,
            "Frames",
            f"{T} motion lines (as 'Frames:' says)",
            f"{len(rows)}" + (" (truncated file)" if len(rows) < T else ""),
        )
    try:  # the C parser checks every row has the same number of columns
        values = np.loadtxt([lines[i] for i in rows], ndmin=2)
    except ValueError:
        values = np.empty((0, 0))
    if values.shape != (T, num_channels) or not np.isfinite(values).all():
        for i in rows:
            toks = lines[i].split()
            if len(toks) != num_channels:
                expected = f"{num_channels} values (one per channel)"
                raise InputError(path, f"line {i + 1}", expected, len(toks))
            for t in toks:
                _float(path, i + 1, "motion value", t)
    return values, dt


def load_bvh(
    path: str | Path, scale: float | None = None, up: str = "y", fps: float | None = None
) -> Motion:
    """Load a BVH file -> :class:`Motion` (metres, z up).

    Rotation channels may come in any order (applied as listed, about the moving axes);
    End Sites become joints ``<joint>_end``.

    Args:
        path: the BVH file.
        scale: metres per file unit; default: detected from the rest-pose height.
        up: the file's up axis, "y" (usual) or "z".
        fps: frame rate; default from the Frame Time line.

    Raises:
        InputError: naming the line and keyword of the first problem.
    """
    path = Path(path)
    if up not in ("y", "z"):
        raise ValueError(f"up must be 'y' or 'z', got {up!r}")
    lines = _read_text(path).splitlines()
    start = next((i for i, s in enumerate(lines) if s.strip().upper() == "MOTION"), None)
    if start is None:
        raise InputError(path, "MOTION", "a MOTION section", "end of file")
    nodes = _bvh_header(path, lines[:start])
    values, dt = _bvh_motion(path, lines, start, sum(len(n.channels) for n in nodes))
    rest, _ = _bvh_fk(nodes, np.zeros((1, values.shape[1])))
    height = float(np.ptp(rest[0, :, "xyz".index(up)]))
    s = _checked_scale(path, height, None, scale)
    P, R = _bvh_fk(nodes, values)
    if fps is None:
        fps = 1.0 / dt
        fps = float(round(fps)) if abs(fps - round(fps)) < 1e-4 * fps else fps  # 0.0083333 s
    return Motion(
        tuple(n.name for n in nodes),
        tuple(n.parent for n in nodes),
        _points_z_up(P, s, up),
        _rotations_z_up(R, up),
        _points_z_up(rest[0] - rest[0, 0], s, up),
        fps,
        str(path),
        s,
    )


def _bvh_fk(nodes: list[_BvhNode], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics in file units and axes. values: (T, C) -> positions (T, J, 3),
    rotations (T, J, 3, 3). Position channels replace the OFFSET on their axis."""
    T, col = values.shape[0], 0
    P = np.empty((T, len(nodes), 3))
    R = np.empty((T, len(nodes), 3, 3))
    for j, node in enumerate(nodes):
        v = values[:, col : col + len(node.channels)]
        col += len(node.channels)
        t = np.broadcast_to(node.offset, (T, 3)).copy()
        rot = [k for k, c in enumerate(node.channels) if c[1] == "r"]
        for k, c in enumerate(node.channels):
            if c[1] == "p":
                t[:, "xyz".index(c[0])] = v[:, k]
        Rl = _euler(np.deg2rad(v[:, rot]), "".join(node.channels[k][0] for k in rot), fixed=False)
        if node.parent < 0:
            P[:, j], R[:, j] = t, Rl
        else:
            Rp = R[:, node.parent]
            P[:, j] = P[:, node.parent] + np.einsum("tij,tj->ti", Rp, t)
            R[:, j] = Rp @ Rl
    return P, R
