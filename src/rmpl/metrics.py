"""Pose metrics: pure functions over arrays in metres.

Shape glossary: ``J`` joints, ``*`` any leading dims. Missing ground-truth joints are NaN
and are left out of every mean; a missing prediction for a present ground truth counts
as an error (see ``missing``).
"""

from __future__ import annotations

import numpy as np

from rmpl.skeleton import SHELF14

__all__ = ["joint_errors", "mpjpe", "pa_mpjpe", "pck", "pcp", "procrustes_align"]


def joint_errors(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Euclidean error per joint, shape (*, J); NaN where the ground truth is missing."""
    pred, gt = np.asarray(pred, float), np.asarray(gt, float)
    if pred.shape != gt.shape or pred.shape[-1] != 3:
        raise ValueError(
            f"pred and gt must both have shape (*, J, 3), got {pred.shape}, {gt.shape}"
        )
    return np.linalg.norm(pred - gt, axis=-1)


def mpjpe(
    pred: np.ndarray,
    gt: np.ndarray,
    joints: tuple[int, ...] | list[int] | None = None,
    missing: float | None = None,
) -> float:
    """Mean per-joint position error, in the units of the input (metres in rmpl).

    Args:
        pred: shape (*, J, 3). gt: shape (*, J, 3); NaN joints are not scored.
        joints: joint indices to score (e.g. :data:`rmpl.skeleton.KP_STAR`); all if None.
        missing: error assigned to a NaN prediction; None leaves such joints out.

    >>> import numpy as np
    >>> gt = np.zeros((2, 3, 3)); pred = gt + [0.0, 0.0, 0.1]
    >>> round(mpjpe(pred, gt), 6)
    0.1
    """
    e = joint_errors(pred, gt)
    if joints is not None:
        e = e[..., list(joints)]
        gt = np.asarray(gt)[..., list(joints), :]
    scored = np.isfinite(np.asarray(gt, float)).all(-1)
    if missing is not None:
        e = np.where(np.isnan(e) & scored, missing, e)
    e = e[scored]
    e = e[np.isfinite(e)]
    return float(e.mean()) if e.size else float("nan")


def procrustes_align(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Similarity-align ``pred`` to ``gt`` per pose (rotation, scale, translation).

    Args:
        pred, gt: shape (*, J, 3); joints NaN in either are ignored for the fit.

    Returns:
        Aligned prediction, shape (*, J, 3).
    """
    pred, gt = np.asarray(pred, float), np.asarray(gt, float)
    ok = (np.isfinite(pred).all(-1) & np.isfinite(gt).all(-1))[..., None]
    n = np.maximum(ok.sum(-2, keepdims=True), 1)
    p0, g0 = np.where(ok, pred, 0), np.where(ok, gt, 0)
    mp, mg = p0.sum(-2, keepdims=True) / n, g0.sum(-2, keepdims=True) / n
    pc, gc = np.where(ok, p0 - mp, 0), np.where(ok, g0 - mg, 0)
    H = np.einsum("...ji,...jk->...ik", pc, gc)
    U, S, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.einsum("...ij,...jk->...ik", U, Vt)))
    D = np.ones_like(S)
    D[..., -1] = d
    R = np.einsum("...ij,...j,...jk->...ik", U, D, Vt)  # pred -> gt: x @ R
    var = (pc**2).sum((-1, -2))
    scale = (S * D).sum(-1) / np.where(var > 0, var, 1)
    return scale[..., None, None] * np.einsum("...ji,...ik->...jk", pred - mp, R) + mg


def pa_mpjpe(pred: np.ndarray, gt: np.ndarray, joints=None) -> float:
    """MPJPE after per-pose Procrustes alignment (rotation, scale, translation)."""
    if joints is not None:
        pred, gt = np.asarray(pred)[..., list(joints), :], np.asarray(gt)[..., list(joints), :]
    return mpjpe(procrustes_align(pred, gt), gt)


def pck(pred: np.ndarray, gt: np.ndarray, threshold: float = 0.150, joints=None) -> float:
    """Percentage of scored joints within ``threshold`` metres (default 150 mm), 0-100.

    A NaN prediction for a present ground truth counts as wrong.
    """
    e = joint_errors(pred, gt)
    g = np.isfinite(np.asarray(gt, float)).all(-1)
    if joints is not None:
        e, g = e[..., list(joints)], g[..., list(joints)]
    hit = np.nan_to_num(e, nan=np.inf) <= threshold
    return float(100.0 * hit[g].mean()) if g.any() else float("nan")


def pcp_parts(pred: np.ndarray, gt: np.ndarray, bones=SHELF14.bones[:10]) -> np.ndarray:
    """Per-part correctness, shape (*, P), bool (NaN-prediction parts are wrong).

    A part (a, b) is correct when the mean of the two end-point errors is at most half
    the ground-truth part length (the Shelf/Campus convention).
    """
    e = np.nan_to_num(joint_errors(pred, gt), nan=np.inf)
    a = np.array([i for i, _ in bones])
    b = np.array([j for _, j in bones])
    length = np.linalg.norm(np.asarray(gt)[..., a, :] - np.asarray(gt)[..., b, :], axis=-1)
    return (e[..., a] + e[..., b]) / 2 <= length / 2


def pcp(pred: np.ndarray, gt: np.ndarray, bones=SHELF14.bones[:10]) -> float:
    """Percentage of correct parts, 0-100, over all poses and parts (Shelf-14 by default).

    The default parts are the ten standard Shelf/Campus parts: head, upper and lower arms,
    upper and lower legs. (The Shelf "torso" part is left to callers.)
    """
    return float(100.0 * pcp_parts(pred, gt, bones).mean())
