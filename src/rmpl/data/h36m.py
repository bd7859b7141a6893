"""Human3.6M in MMPose's ``body3d`` layout (annotation npz + 2D detection npy + cameras.pkl).

The layout on disk (``root``), as written by MMPose's ``preprocess_h36m.py`` and used by
its ``Body3DH36MDataset`` (file names are arguments of :func:`load_h36m`)::

    <root>/<annotations>.npz      e.g. h36m_test.npz (the test fixture: test_h36m_body3d.npz)
    <root>/<detections>.npy       optional, e.g. the fixture's test_h36m_2d_detection.npy
    <root>/cameras.pkl

- The annotation npz holds one sample per image, i.e. per (subject, action, camera,
  frame), S samples in all:

  - ``imgname`` (S,) str: ``S<n>/S<n>_<action>.<camera id>/S<n>_<action>.<camera
    id>_<frame, 6 digits>.jpg``;
  - ``S`` (S, 17, 4): the 3D joints **in the camera's coordinates**, metres, and a
    visibility flag (x, y, z, v);
  - ``part`` (S, 17, 3): the 2D ground truth, the projection of ``S`` in pixels with
    the camera's lens distortion, and a visibility flag;
  - ``center``, ``scale``: the person box (unused here).

- The detection npy, an (S, 17, 3) float array aligned with the samples: x, y in pixels
  and a score, in the H36M-17 joint order. It is read without pickle.
- ``cameras.pkl``: a dict keyed ``(subject, camera id)`` (read by
  :func:`rmpl.io.calibration.load_rig`, format ``h36m-pkl``, restricted unpickler).

Joints: the H36M-17 order MMPose uses (pelvis, right hip, knee, ankle, left hip, knee,
ankle, spine, thorax, neck base, head, left shoulder, elbow, wrist, right shoulder, elbow,
wrist) is, index for index, :data:`rmpl.skeleton.H36M17` (whose "torso", "neck", "nose"
are MMPose's spine, thorax and neck base). The ground truth stays H36M-17. The 2D input
becomes COCO-17 by joint name: the twelve limb joints and the nose (H36M's neck base,
approximately the nose); eyes and ears are missing (NaN, score 0).

The samples of one subject are regrouped into synchronised views: T is the number of
distinct (action, frame) pairs, the views are the subject's four cameras in
``cameras.pkl`` order, and a view without a sample in that frame is NaN. The 3D ground
truth is moved into world coordinates (metres, z up) with each view's extrinsics and
averaged over the views that have it. Each dataset holds one subject because each subject
has its own extrinsics. VideoPose3D's ``data_3d_h36m.npz`` / ``data_2d_h36m_*.npz``
(pickled dicts of object arrays) are not read.
"""

from __future__ import annotations

import logging
import re
import zipfile
from pathlib import Path

import numpy as np

from rmpl.data.base import MultiViewDataset, coco17_by_name
from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.skeleton import H36M17

__all__ = ["SOURCES", "load_h36m", "h36m_subjects"]

log = logging.getLogger(__name__)

#: Where the 2D keypoints come from: the detection file, the ``part`` ground truth, or none.
SOURCES = ("detection", "gt", "none")
_IMGNAME = re.compile(r"(S\d+)/S\d+_(.+)\.(\d+)/[^/]*?(\d+)\.\w+")


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise InputError(path, None, "an existing annotation .npz", "no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        raise InputError(
            path, None, "an .npz of plain arrays", f"{type(e).__name__}: {e}"
        ) from None


def _array(doc: dict, key: str, shape: tuple, path: Path) -> np.ndarray:
    """``doc[key]`` as float with ``shape`` (-1 = the sample count), finite."""
    if key not in doc:
        raise InputError(path, key, f"an array of shape {shape}", "missing")
    a = doc[key]
    if a.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, a.shape, strict=True)):
        raise InputError(path, key, f"shape {shape} (-1: one per sample)", a.shape)
    try:
        a = a.astype(float)
    except (TypeError, ValueError):
        raise InputError(path, key, "numbers", a.dtype) from None
    if not np.all(np.isfinite(a)):
        raise InputError(path, key, "finite numbers", "NaN or inf")
    return a


def _parse_names(names: np.ndarray, path: Path) -> list[tuple[str, str, str, int]]:
    """(subject, action, camera id, frame) of each ``imgname``."""
    out = []
    for i, name in enumerate(names.tolist()):
        m = _IMGNAME.fullmatch(str(name))
        if m is None:
            raise InputError(
                path, f"imgname[{i}]", "S<n>/S<n>_<action>.<camera>/..._<frame>.jpg", name
            )
        out.append((m[1], m[2], m[3], int(m[4])))
    return out


def h36m_subjects(root: str | Path, annotations: str = "test_h36m_body3d.npz") -> list[str]:
    """The subjects present in an annotation file, e.g. ``["S9", "S11"]``."""
    _, samples = _read_samples(Path(root) / annotations)
    subjects = {s for s, *_ in samples}
    return sorted(subjects, key=lambda s: int(s[1:]))


def _read_samples(path: Path) -> tuple[dict, list[tuple[str, str, str, int]]]:
    """The annotation npz's arrays, and (subject, action, camera id, frame) per sample."""
    doc = _load_npz(path)
    if "imgname" not in doc:
        raise InputError(path, "imgname", "image names, shape (S,)", "missing")
    return doc, _parse_names(doc["imgname"], path)


def _to_world(X: np.ndarray, rig: Rig, view: np.ndarray) -> np.ndarray:
    """Camera coordinates (S, J, 3) of the cameras ``view`` (S,) -> world, metres."""
    R, t = rig.R[view], rig.t[view]  # (S, 3, 3), (S, 3)
    return np.einsum("sji,snj->sni", R, X - t[:, None])  # R^T (x - t)


def _coco17(points: np.ndarray, scores: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """H36M-17 (*, 17, 2) and (*, 17) -> COCO-17 by joint name; the others NaN / 0."""
    idx = coco17_by_name(H36M17)
    xy, sc = points[..., np.maximum(idx, 0), :], scores[..., np.maximum(idx, 0)]
    xy[..., idx < 0, :], sc[..., idx < 0] = np.nan, 0.0
    missing = np.isnan(xy).any(-1) | ~(sc > 0)
    xy[missing], sc[missing] = np.nan, 0.0
    return xy, sc


def _keypoints_2d(root: Path, doc: dict, path: Path, source: str, detections: str):
    """The 2D input of every sample, H36M-17: (S, 17, 2) pixels and (S, 17) scores."""
    if source == "none":
        return None
    if source == "gt":
        part = _array(doc, "part", (-1, 17, 3), path)
        return part[..., :2], part[..., 2]
    det_path = root / detections
    if not det_path.is_file():
        raise InputError(
            det_path, None, "the 2D detection .npy (or source='gt'/'none')", "no such file"
        )
    try:
        det = np.load(det_path, allow_pickle=False)
    except (OSError, ValueError) as e:
        raise InputError(det_path, None, "a plain .npy array", f"{type(e).__name__}: {e}") from None
    det = _array({"detections": det}, "detections", (len(doc["imgname"]), 17, 3), det_path)
    return det[..., :2], det[..., 2]


def load_h36m(
    root: str | Path,
    subject: str | None = None,
    *,
    annotations: str = "test_h36m_body3d.npz",
    detections: str = "test_h36m_2d_detection.npy",
    cameras: str = "cameras.pkl",
    source: str = "detection",
) -> MultiViewDataset:
    """Load one Human3.6M subject from MMPose's layout (see the module docstring).

    Args:
        root: the folder holding the files below.
        subject: e.g. "S9"; None when the annotations hold a single subject.
        annotations: the annotation npz, relative to ``root``.
        detections: the 2D detection npy, relative to ``root`` (used by ``source``
            "detection").
        cameras: the cameras pickle, relative to ``root``.
        source: 2D input, one of :data:`SOURCES`: "detection" (the detection file),
            "gt" (the annotations' ``part``), "none" (keypoints None).

    Returns:
        A :class:`~rmpl.data.base.MultiViewDataset`: ground truth H36M-17 in world
        metres, shape (T, 1, 17, 3); keypoints COCO-17, shape (T, 4, 1, 17, 2); ``clips``
        the action of each frame, ``frames`` the frame numbers of the image names.

    Raises:
        InputError: a missing or malformed file, an unknown or ambiguous subject, or
            a camera id missing from ``cameras.pkl``.
    """
    from rmpl.io.calibration import load_rig

    root = Path(root)
    if source not in SOURCES:
        raise InputError(None, "source", f"one of {SOURCES}", source)
    path = root / annotations
    doc, samples = _read_samples(path)
    S3 = _array(doc, "S", (len(samples), 17, 4), path)
    subject = _choose_subject(samples, subject, path)
    rig = load_rig(root / cameras, "h36m-pkl", subject=subject)
    mine, keys, t_of, v_of = _frames_and_views(samples, subject, rig, root / cameras)
    gt = _world_gt(S3[mine], rig, t_of, v_of, len(keys))
    two_d = _keypoints_2d(root, doc, path, source, detections)
    keypoints, scores = _to_views(two_d, mine, t_of, v_of, (len(keys), len(rig)))
    frames = np.array([f for _, f in keys], dtype=int)
    clips = np.array([a for a, _ in keys], dtype=str)
    return MultiViewDataset(
        rig, frames, gt, H36M17.name, keypoints, scores, f"h36m/{subject}", clips=clips
    )


def _choose_subject(samples: list[tuple], subject: str | None, path: Path) -> str:
    """``subject``, or the only subject of the samples when None; checked."""
    subjects = sorted({s for s, *_ in samples})
    if subject is None and len(subjects) != 1:
        raise InputError(path, "subject", "a subject (the file holds several)", subjects)
    subject = subject or subjects[0]
    if subject not in subjects:
        raise InputError(path, "subject", f"one of {subjects}", subject)
    return subject


def _frames_and_views(samples: list[tuple], subject: str, rig: Rig, cameras: Path):
    """Where the subject's samples go among its synchronised views.

    Returns:
        the subject's sample indices (S_subject,); the sorted (action, frame) keys, one per
        output frame (T); and each sample's frame index and view index, (S_subject,) each.
    """
    mine = [i for i, s in enumerate(samples) if s[0] == subject]
    keys = sorted({(samples[i][1], samples[i][3]) for i in mine})
    row = {k: t for t, k in enumerate(keys)}
    unknown = sorted({samples[i][2] for i in mine} - set(rig.names))
    if unknown:
        raise InputError(cameras, f"({subject!r}, camera)", f"cameras {rig.names}", unknown)
    t_of = np.array([row[samples[i][1], samples[i][3]] for i in mine])
    v_of = np.array([rig.names.index(samples[i][2]) for i in mine])
    return mine, keys, t_of, v_of


def _world_gt(S3: np.ndarray, rig: Rig, t_of: np.ndarray, v_of: np.ndarray, T: int):
    """Camera-frame joints with visibility (S, 17, 4) -> the world mean over the views that
    see each joint, (T, 1, 17, 3) metres, NaN when no view does."""
    world = _to_world(S3[:, :, :3], rig, v_of)  # (S, 17, 3)
    seen = S3[:, :, 3:] > 0  # (S, 17, 1) the visibility flag
    total, count = np.zeros((T, 17, 3)), np.zeros((T, 17, 1))
    np.add.at(total, t_of, np.where(seen, world, 0.0))
    np.add.at(count, t_of, seen.astype(float))
    with np.errstate(invalid="ignore"):
        return (total / count)[:, None]


def _to_views(two_d, mine: list[int], t_of, v_of, shape: tuple[int, int]):
    """The 2D of every sample, H36M-17 (S, 17, 2) and (S, 17), or None -> the subject's
    samples ``mine`` in COCO-17, each in its (frame, view) of ``shape`` (T, V):
    (T, V, 1, 17, 2) pixels and (T, V, 1, 17), NaN / 0 elsewhere; or None, None."""
    if two_d is None:
        return None, None
    xy, sc = _coco17(two_d[0][mine], two_d[1][mine])
    keypoints, scores = np.full((*shape, 1, 17, 2), np.nan), np.zeros((*shape, 1, 17))
    keypoints[t_of, v_of, 0], scores[t_of, v_of, 0] = xy, sc
    return keypoints, scores
