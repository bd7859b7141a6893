"""Shelf and Campus in the layout of the VoxelPose release (``actorsGT.mat`` + json + pkl).

A folder (``root``) for dataset ``name`` ("shelf" or "campus") holds:

- ``actorsGT.mat``: a MATLAB file with two cell arrays, each of shape (1, P), one cell
  per actor (Shelf P = 4, Campus P = 3):

  - ``actor3D{p}``: a (T, 1) cell array; row ``t`` (frame ``t`` of the video, counted
    from 0) holds the actor's 14 joints as a 14 x 3 matrix in metres (world, z up), or an
    empty matrix when the actor is not annotated in that frame;
  - ``actor2D{p}`` (optional): a (T, 1) cell array of (1, V) cells, each a 14 x 2 matrix
    of pixels, the 2D annotation of the actor in every view (empty when absent).

  The joints are the Shelf/Campus 14 (:data:`rmpl.skeleton.SHELF14`): right ankle, knee,
  hip, left hip, knee, ankle, right wrist, elbow, shoulder, left shoulder, elbow, wrist,
  neck (bottom of the head), head top.
- ``calibration_<name>.json``: VoxelPose's cameras ``"0"``, ``"1"``, ... (read by
  :func:`rmpl.io.calibration.load_rig`, format ``voxelpose``: ``T`` is the camera
  centre in millimetres). It stores no image size; the datasets' sizes are set here:
  Shelf 1032 x 776, Campus 360 x 288.
- ``pred_<name>_maskrcnn_hrnet_coco.pkl`` (optional): VoxelPose's 2D input, a pickled
  dict keyed ``"<camera>_<frame>"`` (e.g. ``"3_300"``), each a list of detected people
  ``{"pred": (17, 3) array}``: COCO-17 x, y in pixels and the HRNet score, from a Mask
  R-CNN box and HRNet heatmaps. Missing keys mean nobody was detected. The pickle is read
  with an unpickler that accepts only plain containers and numpy arrays (plus the
  ``collections.defaultdict`` VoxelPose saves, with a ``list`` or ``dict`` factory).
- ``panoptic_training_pose.pkl``: CMU Panoptic 3D poses (COCO-17, millimetres) that
  VoxelPose samples to synthesise training heatmaps. Not ground truth of this dataset;
  ignored.
"""

from __future__ import annotations

import dataclasses
import logging
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rmpl.data.base import MultiViewDataset
from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.skeleton import SHELF14

__all__ = [
    "IMAGE_SIZES",
    "NUM_VIEWS",
    "EVAL_FRAMES",
    "load_actors_gt",
    "load_campus_layout",
    "load_hrnet_predictions",
]

log = logging.getLogger(__name__)

#: Image (width, height) in pixels of each dataset's cameras.
IMAGE_SIZES = {"shelf": (1032, 776), "campus": (360, 288)}
#: Number of cameras of each dataset.
NUM_VIEWS = {"shelf": 5, "campus": 3}
#: The frames customarily evaluated (as in VoxelPose): Shelf 300-600, Campus 350-470 and
#: 650-750, inclusive.
EVAL_FRAMES = {
    "shelf": tuple(range(300, 601)),
    "campus": (*range(350, 471), *range(650, 751)),
}
_KEY = re.compile(r"(\d+)_(\d+)")


# --------------------------------------------------------------------------- actorsGT.mat


def _loadmat(path: Path) -> dict:
    import scipy.io

    if not path.is_file():
        raise InputError(path, None, "an existing actorsGT.mat", "no such file")
    try:
        return scipy.io.loadmat(path)
    except Exception as e:  # scipy raises several types for a file that is not a .mat
        raise InputError(path, None, "a MATLAB .mat file", f"{type(e).__name__}: {e}") from None


def _actor_cells(doc: dict, key: str, path: Path) -> list[np.ndarray]:
    """The P cells of ``key``, each flattened to its T rows."""
    cells = doc.get(key)
    if not isinstance(cells, np.ndarray) or cells.dtype != object or cells.ndim != 2:
        got = "missing" if cells is None else f"{type(cells).__name__} {np.shape(cells)}"
        raise InputError(path, key, "a 1 x P cell array (one cell per actor)", got)
    rows = [np.asarray(c).ravel() for c in cells.ravel()]
    if not rows:
        raise InputError(path, key, "at least one actor", "an empty cell array")
    lengths = {len(r) for r in rows}
    if len(lengths) > 1:
        raise InputError(path, key, "the same number of frames for every actor", sorted(lengths))
    return rows


def _matrix(x: object, shape: tuple[int, int], path: Path, field: str) -> np.ndarray | None:
    """A float matrix of ``shape``, or None for MATLAB's empty matrix."""
    a = np.asarray(x)
    if a.size == 0:
        return None
    if a.dtype == object or a.shape != shape:
        raise InputError(path, field, f"a {shape[0]} x {shape[1]} matrix or []", a.shape)
    a = a.astype(float)  # Campus stores some 2D annotations as uint8/uint16
    if not np.all(np.isfinite(a)):
        raise InputError(path, field, "finite numbers", "NaN or inf")
    return a


def load_actors_gt(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Read an ``actorsGT.mat`` (see the module docstring).

    Args:
        path: the file.

    Returns:
        ``gt3d``, shape (T, P, 14, 3), metres, and ``gt2d``, shape (T, P, V, 14, 2),
        pixels, or None when the file has no ``actor2D``; NaN where an actor is absent.

    Raises:
        InputError: not a .mat file, or cells of the wrong shape.
    """
    path = Path(path)
    doc = _loadmat(path)
    J = SHELF14.num_joints
    rows = _actor_cells(doc, "actor3D", path)
    T, P = len(rows[0]), len(rows)
    gt3d = np.full((T, P, J, 3), np.nan)
    for p, actor in enumerate(rows):
        for t, cell in enumerate(actor):
            x = _matrix(cell, (J, 3), path, f"actor3D{{{p + 1}}}{{{t + 1}}}")
            if x is not None:
                gt3d[t, p] = x
    if "actor2D" not in doc:
        return gt3d, None
    rows2 = _actor_cells(doc, "actor2D", path)
    if (len(rows2[0]), len(rows2)) != (T, P):
        raise InputError(
            path,
            "actor2D",
            f"{P} actors x {T} frames as actor3D",
            f"{len(rows2)} x {len(rows2[0])}",
        )
    V = max(np.asarray(c).size for actor in rows2 for c in actor)
    gt2d = np.full((T, P, V, J, 2), np.nan)
    for p, actor in enumerate(rows2):
        for t, views in enumerate(actor):
            for v, cell in enumerate(np.asarray(views).ravel()):
                x = _matrix(cell, (J, 2), path, f"actor2D{{{p + 1}}}{{{t + 1}}}{{{v + 1}}}")
                if x is not None:
                    gt2d[t, p, v] = x
    return gt3d, gt2d


# --------------------------------------------------------------------------- predictions


def _load_pickle(path: Path) -> object:
    """A pickle of plain containers, numpy arrays and ``collections.defaultdict``."""
    from rmpl.io.calibration import load_plain_pickle

    return load_plain_pickle(path)


def _person(item: object, path: Path, field: str) -> np.ndarray:
    pred = item.get("pred") if isinstance(item, dict) else None
    a = np.asarray(pred, dtype=float) if isinstance(pred, np.ndarray | list) else None
    if a is None or a.shape != (17, 3):
        got = "no 'pred'" if a is None else a.shape
        raise InputError(path, f"{field}.pred", "a (17, 3) array of x, y, score", got)
    return a


def load_hrnet_predictions(
    path: str | Path, rig: Rig, frames: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Read VoxelPose's ``pred_<name>_maskrcnn_hrnet_coco.pkl`` for some frames.

    Args:
        path: the pickle (see the module docstring).
        rig: the cameras; key ``"<v>_<frame>"`` is the camera named ``str(v)``.
        frames: the frame numbers to keep, shape (T,).

    Returns:
        keypoints, shape (T, V, N, 17, 2), COCO-17 pixels, NaN where missing, and scores,
        shape (T, V, N, 17), 0 where missing; N is the most people in one view and frame.

    Raises:
        InputError: not such a pickle, a malformed key or person, or detections for a
            camera that is not in the rig.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "an existing predictions pickle", "no such file")
    doc = _load_pickle(path)
    if not isinstance(doc, dict):
        raise InputError(path, None, 'a dict keyed "<camera>_<frame>"', type(doc).__name__)
    view = {name: v for v, name in enumerate(rig.names)}
    row = {int(f): t for t, f in enumerate(frames)}
    found: dict[tuple[int, int], list[np.ndarray]] = {}
    for key, people in doc.items():
        m = _KEY.fullmatch(str(key))
        if m is None or not isinstance(people, list):
            got = f"{key!r}: {type(people).__name__}"
            raise InputError(path, None, 'keys "<camera>_<frame>" holding lists', got)
        if people and m[1] not in view:
            raise InputError(path, str(key), f"detections of the cameras {rig.names}", m[1])
        if people and int(m[2]) in row:
            found[row[int(m[2])], view[m[1]]] = [
                _person(item, path, f"{key}[{i}]") for i, item in enumerate(people)
            ]
    N = max((len(p) for p in found.values()), default=0)
    data = np.full((len(frames), len(rig), N, 17, 3), np.nan)
    for (t, v), people in found.items():
        data[t, v, : len(people)] = np.stack(people)
    keypoints, scores = data[..., :2], np.nan_to_num(data[..., 2])
    missing = np.isnan(keypoints).any(-1) | ~(scores > 0)
    keypoints[missing], scores[missing] = np.nan, 0.0
    return keypoints, scores


# --------------------------------------------------------------------------- the dataset


def _load_rig(root: Path, name: str) -> Rig:
    from rmpl.io.calibration import load_rig

    path = root / f"calibration_{name}.json"
    if not path.is_file():
        raise InputError(path, None, f"the {name} calibration file", "no such file")
    rig = load_rig(path, "voxelpose")
    names = [str(v) for v in range(NUM_VIEWS[name])]
    if sorted(rig.names) != names:
        raise InputError(path, "cameras", f"cameras named {names}", rig.names)
    size = IMAGE_SIZES[name]
    return Rig(tuple(dataclasses.replace(rig[rig.names.index(n)], size=size) for n in names))


def load_campus_layout(
    root: str | Path, dataset: str = "shelf", frames: Sequence[int] | None = None
) -> MultiViewDataset:
    """Load Shelf or Campus from a folder in the VoxelPose layout (module docstring).

    Args:
        root: the folder holding actorsGT.mat, calibration_<dataset>.json and, optionally,
            pred_<dataset>_maskrcnn_hrnet_coco.pkl.
        dataset: "shelf" or "campus".
        frames: frame numbers (rows of actorsGT, from 0) to keep, e.g.
            ``EVAL_FRAMES["shelf"]``; None keeps every frame.

    Returns:
        A :class:`~rmpl.data.base.MultiViewDataset` with ground truth, shape
        (T, P, 14, 3) in metres (Shelf-14), and the HRNet keypoints when the
        predictions file is present (else None).

    Raises:
        InputError: an unknown dataset, a missing or malformed file, or frames outside
            the ground truth.
    """
    root = Path(root)
    if dataset not in NUM_VIEWS:
        raise InputError(root, "dataset", f"one of {sorted(NUM_VIEWS)}", dataset)
    if not root.is_dir():
        raise InputError(root, None, f"a {dataset} folder (actorsGT.mat, calibration json)")
    rig = _load_rig(root, dataset)
    gt, _ = load_actors_gt(root / "actorsGT.mat")
    keep = np.arange(len(gt)) if frames is None else np.asarray(list(frames), dtype=int)
    if keep.ndim != 1 or np.any(keep < 0) or np.any(keep >= len(gt)):
        raise InputError(
            root / "actorsGT.mat",
            "frames",
            f"frame numbers in 0..{len(gt) - 1}",
            f"{keep.min(initial=0)}..{keep.max(initial=0)}",
        )
    pred = root / f"pred_{dataset}_maskrcnn_hrnet_coco.pkl"
    keypoints = scores = None
    if pred.is_file():
        keypoints, scores = load_hrnet_predictions(pred, rig, keep)
    else:
        log.info("%s: no 2D predictions; keypoints are None", pred)
    return MultiViewDataset(rig, keep, gt[keep], SHELF14.name, keypoints, scores, dataset)
