"""The Shelf benchmark in the layout of the 4D-association release.

A Shelf folder (``root``) holds:

- ``calibration.json``: the 5 cameras (read by :func:`rmpl.io.calibration.load_rig`);
- ``gt.txt``: header ``15 T``; per frame the number of people, then per person its id
  (0..3) and a 4 x 15 matrix (rows x, y, z, 1; metres, z up);
- ``detection/<v>.txt``: header ``4 T`` (4 = BODY_25); per frame, for each of the 25
  BODY_25 joints a count n and three rows of n numbers (x, y normalised to [0, 1],
  score), then for each of the 26 BODY_25 limbs (:data:`rmpl.pipeline.association.BODY25_LIMBS`)
  an n_a x n_b matrix of part-affinity scores;
- ``first_frame.txt``: the Shelf frame number of the first frame.

Every text file is parsed as whitespace-separated tokens. Ground-truth ids 0..3 are the
customary actors 1..4 (the actor order of Shelf's ``actorsGT.mat``); the 15 joints are
the Shelf-14 joints (:data:`rmpl.skeleton.SHELF14`) followed by the mid-hip.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.pipeline.association import BODY25_LIMBS, Candidates

__all__ = ["ShelfData", "load_shelf", "NUM_ACTORS", "NUM_VIEWS"]

NUM_ACTORS = 4
NUM_VIEWS = 5
_GT_JOINTS = 15
_BODY25_JOINTS = 25
_BODY25_CODE = 4  # the 4D-association skeleton code of BODY_25, the detection header


@dataclass(frozen=True)
class ShelfData:
    """One Shelf sequence.

    Attributes:
        rig: the 5 cameras, in the order of the detection files 0..4.
        frames: Shelf frame numbers, shape (T,), int.
        gt: ground truth, shape (T, 4, 15, 3), metres (z up); NaN where an actor is
            absent. Actor ids 0..3 are the customary actors 1..4.
        detections: ``detections[t][v]``: the BODY_25 candidates (pixels) and
            part-affinity scores of frame t in view v.
    """

    rig: Rig
    frames: np.ndarray
    gt: np.ndarray
    detections: tuple[tuple[Candidates, ...], ...]

    def __len__(self) -> int:
        return len(self.frames)


class _Tokens:
    """Whitespace tokens of a text file, read in order, with errors that name the file."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            text = path.read_text()
        except OSError as e:
            raise InputError(path, None, "a readable Shelf text file", repr(e)) from None
        try:
            self.values = np.array(text.split(), dtype=float)
        except ValueError:
            raise InputError(path, None, "whitespace-separated numbers only") from None
        self.pos = 0

    def take(self, n: int, field: str) -> np.ndarray:
        if self.pos + n > len(self.values):
            raise InputError(
                self.path,
                field,
                f"{n} more number(s) at token {self.pos}",
                f"end of file after {len(self.values)} tokens",
            )
        out = self.values[self.pos : self.pos + n]
        self.pos += n
        return out

    def count(self, field: str, low: int = 0, high: int | None = None) -> int:
        x = float(self.take(1, field)[0])
        if x != int(x) or x < low or (high is not None and x > high):
            span = f"in {low}..{high}" if high is not None else f">= {low}"
            raise InputError(self.path, field, f"an integer {span} (token {self.pos - 1})", x)
        return int(x)

    def done(self) -> None:
        if self.pos != len(self.values):
            raise InputError(
                self.path,
                None,
                f"exactly {self.pos} tokens",
                f"{len(self.values) - self.pos} extra token(s) at the end",
            )


def _header(tok: _Tokens, first: int, what: str) -> int:
    code = tok.count(f"header ({what})")
    if code != first:
        raise InputError(tok.path, f"header ({what})", f"first token {first}", code)
    return tok.count("header (number of frames)")


def _load_gt(path: Path) -> np.ndarray:
    """Ground truth, shape (T, 4, 15, 3), metres; NaN where an actor is absent."""
    tok = _Tokens(path)
    T = _header(tok, _GT_JOINTS, "number of joints")
    gt = np.full((T, NUM_ACTORS, _GT_JOINTS, 3), np.nan)
    for t in range(T):
        for p in range(tok.count(f"frame {t}: number of people", 0, NUM_ACTORS)):
            i = tok.count(f"frame {t}, person {p}: actor id", 0, NUM_ACTORS - 1)
            m = tok.take(4 * _GT_JOINTS, f"frame {t}, actor {i}: 4 x 15 matrix")
            gt[t, i] = m.reshape(4, _GT_JOINTS)[:3].T
    tok.done()
    if not np.isfinite(gt).any(-1).any(-1).any():
        raise InputError(path, None, "at least one person")
    return gt


def _load_detections(path: Path, size: tuple[int, int]) -> list[Candidates]:
    """One view's BODY_25 candidates per frame; pixels = x (W - 1), y (H - 1)."""
    tok = _Tokens(path)
    T = _header(tok, _BODY25_CODE, "skeleton code, 4 = BODY_25")
    scale = np.array([size[0] - 1, size[1] - 1, 1.0])
    values, counts = tok.values, tok.values.tolist()
    end = len(counts)
    out = []
    for t in range(T):
        points = []
        for j in range(_BODY25_JOINTS):
            pos = tok.pos
            n = counts[pos] if pos < end else -1.0
            if not (n >= 0 and n == int(n)):  # the checked read names the problem
                tok.count(f"frame {t}, joint {j}: candidate count")
            n = int(n)
            if pos + 1 + 3 * n > end:
                tok.pos = pos + 1
                tok.take(3 * n, f"frame {t}, joint {j}: 3 x {n} candidates")
            points.append(values[pos + 1 : pos + 1 + 3 * n].reshape(3, n).T * scale)
            tok.pos = pos + 1 + 3 * n
        affinities = []
        for a, b in BODY25_LIMBS:
            na, nb = len(points[a]), len(points[b])
            pos = tok.pos
            if pos + na * nb > end:
                tok.take(na * nb, f"frame {t}, limb ({a}, {b}): {na} x {nb} affinities")
            affinities.append(values[pos : pos + na * nb].reshape(na, nb))
            tok.pos = pos + na * nb
        out.append(Candidates(tuple(points), tuple(affinities), BODY25_LIMBS, "body25"))
    tok.done()
    return out


def _load_rig(root: Path) -> Rig:
    from rmpl.io.calibration import load_rig

    path = root / "calibration.json"
    rig = load_rig(path)
    names = [str(v) for v in range(NUM_VIEWS)]
    if sorted(rig.names) != names:
        raise InputError(path, "cameras", f"cameras named {names}", rig.names)
    rig = rig[[rig.names.index(n) for n in names]]
    for cam in rig:
        if cam.size is None:
            raise InputError(path, f"{cam.name}.imgSize", "the image size [width, height]")
    return rig


def load_shelf(root: str | Path) -> ShelfData:
    """Load a Shelf folder in the 4D-association layout (see the module docstring).

    Args:
        root: the folder holding calibration.json, gt.txt, first_frame.txt, detection/.

    Returns:
        :class:`ShelfData`.

    Raises:
        InputError: naming the file and field when a file is missing or malformed.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, None, "a Shelf folder (calibration.json, gt.txt, detection/)")
    rig = _load_rig(root)
    gt = _load_gt(root / "gt.txt")
    T = len(gt)
    first = _Tokens(root / "first_frame.txt")
    start = first.count("first frame number")
    first.done()
    views = []
    for v, cam in enumerate(rig):
        dets = _load_detections(root / "detection" / f"{v}.txt", cam.size)
        if len(dets) != T:
            raise InputError(
                root / "detection" / f"{v}.txt",
                "header (number of frames)",
                f"{T} frames, as in gt.txt",
                len(dets),
            )
        views.append(dets)
    detections = tuple(zip(*views, strict=True))
    return ShelfData(rig, start + np.arange(T), gt, detections)
