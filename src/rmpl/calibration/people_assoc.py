"""Who is who, once cameras exist: the people of every frame associated across views
through the current calibration, and linked over time into persons.

Calibration from people starts from people matched by their 2D tracks alone
(:mod:`rmpl.calibration.people`): a track that jumps from one person to another, or a
person split into many short tracks, leaves wrong or weak correspondences in the first
adjustment. Once the cameras are within a few degrees, each frame's 2D people are
associated again, frame by frame, by the distance between their joints' camera rays
(:func:`rmpl.pipeline.association.associate`), triangulated, and linked frame to frame
into persons (:func:`rmpl.pipeline.tracking.track_indices`), whose bone lengths the next
adjustment holds constant. The ray-distance threshold tightens as the cameras improve
(:data:`MAX_COST`).

Shape glossary: ``T`` frames, ``V`` views, ``P`` 2D people per view, ``G`` persons,
``J`` joints (17, COCO-17). Metres in the units of the current calibration.
"""

from __future__ import annotations

import numpy as np

from rmpl.geometry.camera import Rig

__all__ = ["MAX_COST", "reassociate", "triangulate_normalised"]

#: The largest mean ray-to-ray distance (metres) at which two views' people are one
#: person, per round: loose while the cameras are degrees off, then that of ``rmpl run``.
MAX_COST = (0.3, 0.15)
#: Persons: the gate between a track's predicted and a new pose (mean joint distance,
#: metres), frames a track may miss, and the fewest frames a person needs.
LINK_DISTANCE = 0.5
LINK_MISSED = 5
MIN_FRAMES = 5
J17 = 17


def reassociate(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    max_cost: float,
    min_score: float,
    normalise,
) -> tuple[np.ndarray, np.ndarray, list[dict]]:
    """The persons of a recording through the cameras ``rig``.

    Args:
        keypoints: shape (T, V, P, J, 2), pixels, NaN = missing (COCO-17 first).
        scores: shape (T, V, P, J).
        rig: the current cameras (pixels in, metres of the calibration's units).
        max_cost: the association's ray-distance threshold, metres.
        min_score: joints below this score are missing.
        normalise: ``normalise(points (..., 2) px, camera) -> (..., 2)`` undistorted
            normalised coordinates.

    Returns:
        ``(obs, ids, persons)``: the persons' 2D, shape (T, G, V, 17, 2), normalised, NaN
        where unseen; the observation group of each (person, view), shape (T, G, V), -1
        where unseen; and per person ``{"views": {camera: frames}, "frames": n}``.
    """
    from rmpl.pipeline.association import AssociationConfig, associate
    from rmpl.pipeline.tracking import track_indices

    T, V = keypoints.shape[:2]
    cfg = AssociationConfig(min_score=min_score, max_cost=max_cost)
    kp = np.where((scores[..., :J17] >= min_score)[..., None], keypoints[..., :J17, :], np.nan)
    sc = np.where(np.isfinite(kp).all(-1), scores[..., :J17], 0.0)
    found, poses = [], []
    for t in range(T):
        a = associate(list(kp[t]), list(sc[t]), rig, cfg, skeleton="coco17")
        found.append(a)
        poses.append(_triangulate(a.keypoints, rig, normalise))
    index = track_indices(poses, LINK_DISTANCE, LINK_MISSED, MIN_FRAMES)
    G = index.shape[1]
    obs = np.full((T, G, V, J17, 2), np.nan)
    for t, g in zip(*np.nonzero(index >= 0), strict=True):
        x = found[t].keypoints[index[t, g]]  # (V, J, 2) px
        for v, cam in enumerate(rig):
            if np.isfinite(x[v]).any():
                obs[t, g, v] = normalise(x[v], cam)
    seen = np.isfinite(obs).all(-1).any(-1)  # (T, G, V)
    ids = np.where(seen, np.arange(G)[None, :, None] * V + np.arange(V), -1)
    persons = [
        {
            "views": {cam.name: int(seen[:, g, v].sum()) for v, cam in enumerate(rig)},
            "frames": int(seen[:, g].any(-1).sum()),
        }
        for g in range(G)
    ]
    return obs, ids, persons


def _triangulate(keypoints: np.ndarray, rig: Rig, normalise) -> np.ndarray:
    """The people of one frame, (N, V, J, 2) px -> (N, J, 3), NaN below two views."""
    if not len(keypoints):
        return np.zeros((0, J17, 3))
    x = np.stack([normalise(keypoints[:, v], cam) for v, cam in enumerate(rig)], 1)
    return triangulate_normalised(np.moveaxis(x, 1, 2), rig.R, rig.t, np.ones(len(rig), bool))


def triangulate_normalised(obs: np.ndarray, R: np.ndarray, t: np.ndarray, use) -> np.ndarray:
    """DLT of normalised observations (..., V, 2) through cameras (V, 3, 3), (V, 3); only
    the views in ``use`` (V,) bool. Returns (..., 3), NaN with fewer than two views."""
    P = np.concatenate([R, t[:, :, None]], -1)  # (V, 3, 4)
    ok = np.isfinite(obs).all(-1) & np.asarray(use)
    x = np.nan_to_num(obs)
    rows = np.concatenate([x[..., 0:1] * P[:, 2] - P[:, 0], x[..., 1:2] * P[:, 2] - P[:, 1]], -2)
    rows = rows * np.concatenate([ok, ok], -1)[..., None]  # (..., 2V, 4)
    _, _, vt = np.linalg.svd(rows)
    X = vt[..., -1, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        X = X[..., :3] / X[..., 3:]
    X[ok.sum(-1) < 2] = np.nan
    return X
