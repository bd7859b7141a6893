"""The one shape every real multi-view dataset loader returns: :class:`MultiViewDataset`.

A dataset is a calibrated rig, 3D ground truth per frame and person in world metres, and
(when the dataset has any) the 2D keypoints of every view as COCO-17 pixels. Missing is
NaN (and a score of 0), never a sentinel value.

Shape glossary: ``T`` frames, ``V`` views, ``P`` ground-truth people, ``N`` the most 2D
people detected in one view and frame, ``J`` joints.

People in the 2D keypoints are **not associated across views** (nor across frames): person
``n`` of view 0 and person ``n`` of view 1 need not be the same person, and neither needs
to be ground-truth person ``n``. Associating them is the job of :mod:`rmpl.pipeline.association`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.io.keypoints import Keypoints2D
from rmpl.skeleton import COCO17, SKELETONS, Skeleton

__all__ = [
    "MultiViewDataset",
    "coco17_by_name",
    "keypoints_from_projection",
    "attach_keypoints",
]


@dataclass(frozen=True)
class MultiViewDataset:
    """Calibrated multi-view frames with 3D ground truth and optional 2D keypoints.

    Attributes:
        rig: the V cameras (translations in metres), in the order of the views below.
        frames: frame numbers, shape (T,), int; numbered within a clip (see ``clips``).
        gt: ground-truth joints in world coordinates, shape (T, P, J_gt, 3), metres; NaN
            where a person or a joint is absent.
        gt_skeleton: joint set of ``gt``, a key of :data:`rmpl.skeleton.SKELETONS`.
        keypoints: 2D input, COCO-17 pixels from the image's top-left corner, shape
            (T, V, N, 17, 2); NaN where missing. None when the dataset has no 2D.
        scores: confidence of each keypoint, shape (T, V, N, 17); 0 where missing.
            None exactly when ``keypoints`` is None.
        name: a short name such as ``"shelf"`` or ``"panoptic/160906_band1"``.
        person_ids: the dataset's id of each ground-truth person, shape (P,), or None
            when the people are simply 0..P-1.
        clips: the clip (action, sequence) each frame belongs to, shape (T,), str, or
            None for a single clip.
    """

    rig: Rig
    frames: np.ndarray
    gt: np.ndarray
    gt_skeleton: str
    keypoints: np.ndarray | None
    scores: np.ndarray | None
    name: str
    person_ids: np.ndarray | None = None
    clips: np.ndarray | None = None

    def __post_init__(self) -> None:
        frames = np.asarray(self.frames)
        if frames.ndim != 1 or not np.issubdtype(frames.dtype, np.integer):
            raise InputError(None, "frames", "integer frame numbers, shape (T,)", frames.shape)
        T = len(frames)
        if self.gt_skeleton not in SKELETONS:
            raise InputError(None, "gt_skeleton", f"one of {sorted(SKELETONS)}", self.gt_skeleton)
        J = SKELETONS[self.gt_skeleton].num_joints
        gt = np.asarray(self.gt, dtype=float)
        if gt.ndim != 4 or gt.shape[0] != T or gt.shape[2:] != (J, 3):
            raise InputError(None, "gt", f"shape ({T}, P, {J}, 3) (T, P, J, 3)", gt.shape)
        object.__setattr__(self, "frames", frames)
        object.__setattr__(self, "gt", gt)
        self._check_keypoints(T)
        if self.person_ids is not None:
            ids = np.asarray(self.person_ids)
            if ids.shape != (gt.shape[1],):
                raise InputError(None, "person_ids", f"shape ({gt.shape[1]},) (P,)", ids.shape)
            object.__setattr__(self, "person_ids", ids)
        if self.clips is not None:
            clips = np.asarray(self.clips, dtype=str)
            if clips.shape != (T,):
                raise InputError(None, "clips", f"shape ({T},) (T,)", clips.shape)
            object.__setattr__(self, "clips", clips)

    def _check_keypoints(self, T: int) -> None:
        if (self.keypoints is None) != (self.scores is None):
            raise InputError(None, "scores", "None exactly when keypoints is None")
        if self.keypoints is None:
            return
        V = len(self.rig)
        kp = np.asarray(self.keypoints, dtype=float)
        sc = np.asarray(self.scores, dtype=float)
        if kp.ndim != 5 or kp.shape[:2] != (T, V) or kp.shape[3:] != (COCO17.num_joints, 2):
            raise InputError(None, "keypoints", f"shape ({T}, {V}, N, 17, 2)", kp.shape)
        if sc.shape != kp.shape[:-1]:
            raise InputError(None, "scores", f"shape {kp.shape[:-1]} (T, V, N, 17)", sc.shape)
        nan = np.isnan(kp).any(-1)
        if np.any(sc[nan] != 0) or np.any(~(sc[~nan] >= 0)):
            raise InputError(None, "scores", "0 where keypoints are NaN, finite and >= 0 elsewhere")
        object.__setattr__(self, "keypoints", kp)
        object.__setattr__(self, "scores", sc)

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def num_views(self) -> int:
        return len(self.rig)

    @property
    def num_people(self) -> int:
        """P, the ground-truth people slots."""
        return self.gt.shape[1]


def coco17_by_name(skeleton: str | Skeleton) -> np.ndarray:
    """For each COCO-17 joint, the index of the same-named joint of ``skeleton``, or -1.

    >>> coco17_by_name("shelf14")[5:].tolist()  # shoulders ... ankles
    [9, 8, 10, 7, 11, 6, 3, 2, 4, 1, 5, 0]
    """
    skel = skeleton if isinstance(skeleton, Skeleton) else SKELETONS[skeleton]
    names = set(skel.joints)
    return np.array([skel.index(n) if n in names else -1 for n in COCO17.joints])


def _take_coco17(values: np.ndarray, skeleton: str, fill: float) -> np.ndarray:
    """(*, J, C) joints of ``skeleton`` -> (*, 17, C) COCO-17 by name; the others ``fill``."""
    idx = coco17_by_name(skeleton)
    out = values[..., np.maximum(idx, 0), :]
    out[..., idx < 0, :] = fill
    return out


def keypoints_from_projection(
    dataset: MultiViewDataset,
    noise_px: float = 0.0,
    rng: np.random.Generator | None = None,
) -> MultiViewDataset:
    """A stand-in for a 2D detector: the ground truth projected into every view.

    Each COCO-17 joint with a same-named ground-truth joint is projected with the rig
    (lens distortion included) and, when ``noise_px > 0``, moved by isotropic Gaussian
    noise of that standard deviation in pixels. A joint is missing (NaN, score 0) when
    its ground truth is, when it lies behind the camera, or when it falls outside the
    image of a camera whose size is known; the other joints get score 1. COCO joints
    without a ground-truth counterpart (e.g. eyes and ears for Shelf-14) are missing.

    This is not a detector: the keypoints carry no detector bias, and slot ``n`` of every
    view holds ground-truth person ``n`` (an association is already made). Use it for
    plumbing and for upper bounds, not for results to compare with image-based methods.

    Args:
        dataset: the dataset whose ground truth to project.
        noise_px: standard deviation of the pixel noise.
        rng: random generator for the noise (default: a fresh ``default_rng()``).

    Returns:
        A copy of ``dataset`` with keypoints, shape (T, V, P, 17, 2), and scores.
    """
    if not noise_px >= 0:
        raise ValueError(f"noise_px must be >= 0, got {noise_px}")
    rng = np.random.default_rng() if rng is None else rng
    rig = dataset.rig
    X = _take_coco17(dataset.gt, dataset.gt_skeleton, np.nan)  # (T, P, 17, 3)
    T, P = X.shape[:2]
    flat = X.reshape(T, P * 17, 3)
    uv = rig.project(flat)  # (T, V, P*17, 2); NaN behind the camera
    if noise_px > 0:
        uv = uv + rng.normal(0.0, noise_px, uv.shape)
    size = rig.sizes[:, None, :]  # (V, 1, 2); NaN when unknown
    outside = (uv < 0).any(-1) | (uv > size - 1).any(-1)  # False against NaN sizes
    missing = np.isnan(uv).any(-1) | outside
    uv[missing] = np.nan
    V = len(rig)
    keypoints = uv.reshape(T, V, P, 17, 2)
    scores = np.where(missing, 0.0, 1.0).reshape(T, V, P, 17)
    return dataclasses.replace(dataset, keypoints=keypoints, scores=scores)


def attach_keypoints(dataset: MultiViewDataset, kp: Keypoints2D) -> MultiViewDataset:
    """Give a dataset the 2D keypoints read from files (:func:`rmpl.io.keypoints.load_keypoints`).

    Frames are matched by number, so the dataset must hold a single clip. Dataset frames
    absent from ``kp`` get no keypoints
    (NaN, score 0) and frames of ``kp`` absent from the dataset are dropped. Views are
    matched by name when ``kp.views`` are exactly the rig's camera names (in any order),
    otherwise by position, which needs as many views as cameras.

    Args:
        dataset: the dataset.
        kp: COCO-17 keypoints, shape (T', V, N, 17, 2).

    Returns:
        A copy of ``dataset`` with keypoints, shape (T, V, N, 17, 2), and scores.

    Raises:
        InputError: the keypoints are not COCO-17, their views do not fit the rig, or the
            dataset holds several clips.
    """
    if kp.skeleton != COCO17.name:
        raise InputError(None, "keypoints.skeleton", "coco17", kp.skeleton)
    if dataset.clips is not None and len(set(dataset.clips.tolist())) > 1:
        raise InputError(
            None,
            "dataset.clips",
            "a single clip (frame numbers repeat across clips)",
            sorted(set(dataset.clips.tolist())),
        )
    names = dataset.rig.names
    if sorted(kp.views) == sorted(names):
        order = [kp.views.index(n) for n in names]
    elif kp.num_views == len(names):
        order = list(range(len(names)))
    else:
        raise InputError(
            None, "keypoints.views", f"{len(names)} views or the cameras {names}", kp.views
        )
    T, V, N = len(dataset), len(names), kp.num_people
    keypoints = np.full((T, V, N, 17, 2), np.nan)
    scores = np.zeros((T, V, N, 17))
    row = {int(f): i for i, f in enumerate(kp.frames)}
    have = [(t, row[int(f)]) for t, f in enumerate(dataset.frames) if int(f) in row]
    if have:
        dst, src = (np.array(a) for a in zip(*have, strict=True))
        keypoints[dst] = kp.keypoints[src][:, order]
        scores[dst] = kp.scores[src][:, order]
    return dataclasses.replace(dataset, keypoints=keypoints, scores=scores)
