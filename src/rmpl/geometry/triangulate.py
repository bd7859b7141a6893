"""Triangulation: confidence-weighted DLT, robust view exclusion, recentering.

All functions broadcast over leading dims and treat a keypoint as missing when its score is
zero, below a threshold, or when its pixel is NaN.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from rmpl.geometry.camera import Rig
from rmpl.geometry.rays import pixel_to_normalized

__all__ = [
    "TriangulationResult",
    "triangulate",
    "triangulate_points",
    "triangulate_robust",
    "reprojection_error",
    "recenter_point",
]


@dataclass
class TriangulationResult:
    """Triangulated joints and diagnostics.

    Attributes:
        points: shape (*, J, 3), metres; NaN where the joint could not be triangulated.
        error: mean reprojection error over the views used, shape (*, J), pixels.
        views: which views were used, shape (*, V, J), bool.
    """

    points: np.ndarray
    error: np.ndarray
    views: np.ndarray

    @property
    def num_views(self) -> np.ndarray:
        """Number of views used per joint, shape (*, J)."""
        return self.views.sum(axis=-2)


def _normalized_P(rig: Rig) -> np.ndarray:
    """[R | t] per view, shape (V, 3, 4): the projection in undistorted normalised coords."""
    return np.concatenate([rig.R, rig.t[:, :, None]], axis=-1)


def _dlt(xy: np.ndarray, P: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted DLT.

    Args:
        xy: normalised coordinates, shape (*, V, J, 2), finite.
        P: normalised projections, shape (*, V, 3, 4) broadcastable.
        w: weights, shape (*, V, J); 0 drops a view.

    Returns:
        Points, shape (*, J, 3); NaN where fewer than 2 views have weight.
    """
    lead = np.broadcast_shapes(xy.shape[:-3], P.shape[:-3], w.shape[:-2])
    V, J = xy.shape[-3], xy.shape[-2]
    wj = np.moveaxis(np.broadcast_to(w, (*lead, V, J)), -2, -1)  # (*, J, V)
    enough = (wj > 0).sum(axis=-1) >= 2  # (*, J): only these are solved
    X = np.full((*lead, J, 3), np.nan)
    if not enough.any():
        return X
    xy = np.moveaxis(np.broadcast_to(xy, (*lead, V, J, 2)), -3, -2)[enough]  # (n, V, 2)
    P = np.broadcast_to(P[..., None, :, :, :], (*lead, J, V, 3, 4))[enough]  # (n, V, 3, 4)
    w = wj[enough]  # (n, V)
    r0 = xy[..., 0:1] * P[..., 2, :] - P[..., 0, :]  # (n, V, 4)
    r1 = xy[..., 1:2] * P[..., 2, :] - P[..., 1, :]
    # Rows scaled to unit length so the weight alone sets each view's influence.
    r0 = r0 / np.linalg.norm(r0, axis=-1, keepdims=True)
    r1 = r1 / np.linalg.norm(r1, axis=-1, keepdims=True)
    w2 = (w * w)[..., None, None]
    M = (w2 * (r0[..., :, None] * r0[..., None, :] + r1[..., :, None] * r1[..., None, :])).sum(
        axis=-3
    )  # (n, 4, 4)
    _, vecs = np.linalg.eigh(M)
    h = vecs[..., :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        X[enough] = h[..., :3] / h[..., 3:4]
    return X


def _prepare(keypoints, scores, rig: Rig, min_score: float):
    kp = np.asarray(keypoints, dtype=float)
    sc = np.asarray(scores, dtype=float)
    if kp.ndim < 3 or kp.shape[-1] != 2:
        raise ValueError(f"keypoints must have shape (*, V, J, 2), got {kp.shape}")
    if sc.shape != kp.shape[:-1]:
        raise ValueError(f"scores must have shape {kp.shape[:-1]} (*, V, J), got {sc.shape}")
    if kp.shape[-3] != len(rig):
        raise ValueError(f"keypoints have {kp.shape[-3]} views but the rig has {len(rig)} cameras")
    valid = np.isfinite(kp).all(-1) & np.isfinite(sc) & (sc > 0) & (sc >= min_score)
    xy = pixel_to_normalized(np.where(valid[..., None], kp, 0.0), rig.K[:, None], rig.dist[:, None])
    w = np.where(valid, sc, 0.0)
    return kp, xy, w, valid


def reprojection_error(points: np.ndarray, keypoints: np.ndarray, rig: Rig) -> np.ndarray:
    """Pixel distance between projected points and keypoints.

    Args:
        points: shape (*, J, 3). keypoints: shape (*, V, J, 2).

    Returns:
        shape (*, V, J), pixels (NaN where either side is missing).
    """
    proj = rig.project(points)  # (*, V, J, 2)
    return np.linalg.norm(proj - keypoints, axis=-1)


def triangulate(
    keypoints: np.ndarray, scores: np.ndarray, rig: Rig, min_score: float = 0.0
) -> TriangulationResult:
    """Confidence-weighted DLT over every view that sees each joint.

    Args:
        keypoints: pixels, shape (*, V, J, 2); NaN for missing.
        scores: confidences, shape (*, V, J); 0 for missing.
        rig: the V cameras.
        min_score: keypoints with a lower score are ignored.

    Returns:
        :class:`TriangulationResult`; a joint seen by fewer than 2 views is NaN.

    >>> import numpy as np
    >>> from rmpl.geometry.camera import Camera, Rig, look_at
    >>> K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    >>> eyes = np.array([[3.0, 0, 1.5], [0, 3, 1.5], [-3, 0, 1.5]])
    >>> rig = Rig(tuple(Camera(K, *look_at(e, np.array([0, 0, 1.0])), name=str(i))
    ...                 for i, e in enumerate(eyes)))
    >>> X = np.array([[0.1, -0.2, 1.3]])
    >>> res = triangulate(rig.project(X), np.ones((3, 1)), rig)
    >>> bool(np.allclose(res.points, X, atol=1e-9))
    True
    """
    kp, xy, w, valid = _prepare(keypoints, scores, rig, min_score)
    X = _dlt(xy, _normalized_P(rig), w)
    err = reprojection_error(X, kp, rig)
    mean_err = np.where(valid, err, 0).sum(-2) / np.maximum(valid.sum(-2), 1)
    ok = np.isfinite(X).all(-1)
    return TriangulationResult(X, np.where(ok, mean_err, np.nan), valid & ok[..., None, :])


def triangulate_points(
    keypoints: np.ndarray, scores: np.ndarray, rig: Rig, min_score: float = 0.0
) -> np.ndarray:
    """:func:`triangulate`'s points (*, J, 3) alone, without the reprojection errors."""
    _, xy, w, _ = _prepare(keypoints, scores, rig, min_score)
    return _dlt(xy, _normalized_P(rig), w)


def _subset_masks(num_views: int) -> np.ndarray:
    """Every subset of at least 2 views, shape (S, V), bool."""
    masks = [
        np.isin(np.arange(num_views), c)
        for k in range(2, num_views + 1)
        for c in itertools.combinations(range(num_views), k)
    ]
    return np.array(masks, dtype=bool).reshape(-1, num_views)


def _robust_block(kp, xy, w, valid, rig, masks, max_error, keep_failed):
    """Robust triangulation of a flat block: kp (N, V, J, 2) etc."""
    P = _normalized_P(rig)
    ws = w[:, None] * masks[None, :, :, None]  # (N, S, V, J)
    X = _dlt(xy[:, None], P, ws)  # (N, S, J, 3)
    err = reprojection_error(X, kp[:, None], rig)  # (N, S, V, J)
    used = ws > 0
    n_used = used.sum(-2)
    mean_err = np.where(used, err, 0).sum(-2) / np.maximum(n_used, 1)  # (N, S, J)
    feasible = (masks[None, :, :, None] <= valid[:, None]).all(-2) & (n_used >= 2)
    feasible &= np.isfinite(X).all(-1) & np.isfinite(mean_err)
    level = valid.sum(-2)[:, None] - masks.sum(-1)[None, :, None]  # views excluded
    # Fewest exclusions first; among equal exclusions, the lowest error.
    key = np.where(feasible & (mean_err <= max_error), level * 1e6 + mean_err, np.inf)
    best = key.argmin(axis=1)  # (N, J)
    ok = np.isfinite(np.take_along_axis(key, best[:, None], 1)[:, 0])
    if keep_failed:
        fallback = np.where(feasible, mean_err, np.inf).argmin(axis=1)
        best = np.where(ok, best, fallback)
        ok = np.isfinite(
            np.take_along_axis(np.where(feasible, 0.0, np.inf), best[:, None], 1)[:, 0]
        )
    pts = np.take_along_axis(X, best[:, None, :, None], 1)[:, 0]
    e = np.take_along_axis(mean_err, best[:, None], 1)[:, 0]
    views = np.moveaxis(np.take_along_axis(used, best[:, None, None, :], 1)[:, 0], -1, -1)
    pts[~ok] = np.nan
    e[~ok] = np.nan
    views &= ok[:, None, :]
    return pts, e, views


def _pair_errors(kp, sc, rig, sel, min_score, npairs):
    """Each left/right pair's summed mean reprojection error (*, pairs): the pairs' joints
    ``sel`` (left joints first, then right) triangulated alone."""
    e = triangulate(kp[..., sel, :], sc[..., sel], rig, min_score).error
    return e[..., :npairs] + e[..., npairs:]


def _swap_left_right(kp, sc, rig, flip_pairs, min_score):
    """Per view and left/right pair, swap the two keypoints when that at least halves the
    pair's error (only pairs whose two joints both triangulate as they are)."""
    kp, sc = kp.copy(), sc.copy()
    a_idx = [a for a, _ in flip_pairs]
    b_idx = [b for _, b in flip_pairs]
    sel, k = a_idx + b_idx, len(flip_pairs)
    # A joint's triangulation depends on its own keypoints only: the pairs' joints are
    # triangulated alone, and after a swap the swapped pair's error is the one just tried.
    base_err = _pair_errors(kp, sc, rig, sel, min_score, k)
    for v in range(kp.shape[-3]):
        kp2, sc2 = kp.copy(), sc.copy()
        kp2[..., v, a_idx, :], kp2[..., v, b_idx, :] = kp[..., v, b_idx, :], kp[..., v, a_idx, :]
        sc2[..., v, a_idx], sc2[..., v, b_idx] = sc[..., v, b_idx], sc[..., v, a_idx]
        alt_err = _pair_errors(kp2, sc2, rig, sel, min_score, k)
        # Only where both joints of the pair triangulate as they are: a pair with a joint
        # seen once would otherwise "improve" by borrowing the other side's observation.
        better = np.isfinite(base_err) & (np.nan_to_num(alt_err, nan=np.inf) < 0.5 * base_err)
        for i, (a, b) in enumerate(flip_pairs):
            m = better[..., i]
            kp[m, v, a], kp[m, v, b] = kp2[m, v, a], kp2[m, v, b]
            sc[m, v, a], sc[m, v, b] = sc2[m, v, a], sc2[m, v, b]
        base_err = np.where(better, alt_err, base_err)
    return kp, sc


def _per_joint(a: np.ndarray, lead: tuple, V: int, J: int) -> np.ndarray:
    """(*, V, J, ...) -> (n * J, V, 1, ...): one item per point and joint."""
    rest = a.shape[len(lead) + 2 :]
    a = np.moveaxis(a.reshape(-1, V, J, *rest), 2, 1)
    return a.reshape(-1, V, 1, *rest)


def _all_views(kp, xy, w, valid, rig, max_error):
    """The search's first candidate, every view that sees the joint, of items (n, V, 1, ·):
    points (n, 1, 3), mean error (n, 1), and whether it is the answer (n, 1): triangulated
    from two or more views within ``max_error`` (no other subset then excludes as few)."""
    X = _dlt(xy, _normalized_P(rig), w)
    err = reprojection_error(X, kp, rig)
    n_used = valid.sum(-2)
    mean_err = np.where(valid, err, 0).sum(-2) / np.maximum(n_used, 1)
    done = (n_used >= 2) & np.isfinite(X).all(-1) & np.isfinite(mean_err)
    return X, mean_err, done & (mean_err <= max_error)


def triangulate_robust(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    min_score: float = 0.3,
    max_error: float = 15.0,
    swap_pairs: tuple[tuple[int, int], ...] | None = None,
    keep_failed: bool = False,
    block: int = 256,
) -> TriangulationResult:
    """Triangulation with view exclusion, at least as strong as Pose2Sim's.

    For every joint: drop views with score < ``min_score``; among the subsets of the
    remaining views that exclude the fewest views, keep the one with the lowest mean
    reprojection error once that error is at most ``max_error`` pixels (the subsets are
    searched exhaustively, fewest exclusions first). Each candidate is a
    confidence-weighted DLT.

    Args:
        keypoints: pixels, shape (*, V, J, 2).
        scores: confidences, shape (*, V, J).
        rig: the V cameras.
        min_score: likelihood threshold.
        max_error: reprojection error threshold, pixels.
        swap_pairs: (left, right) joint pairs to test for left/right swaps per view
            before the search (e.g. ``COCO17.flip_pairs``); None skips the check.
        keep_failed: when no subset reaches ``max_error``, keep the lowest-error subset
            instead of returning NaN.
        block: points processed at once (bounds memory).

    Returns:
        :class:`TriangulationResult`.
    """
    kp0 = np.asarray(keypoints, dtype=float)
    sc0 = np.asarray(scores, dtype=float)
    if swap_pairs:
        kp0, sc0 = _swap_left_right(kp0, sc0, rig, list(swap_pairs), min_score)
    kp, xy, w, valid = _prepare(kp0, sc0, rig, min_score)
    lead = kp.shape[:-3]
    V, J = kp.shape[-3], kp.shape[-2]
    items = [_per_joint(a, lead, V, J) for a in (kp, xy, w, valid)]
    # Fewest exclusions first: most joints are answered by all their views; the subsets
    # are searched only for the others (those two or more views see).
    X, mean_err, done = _all_views(*items, rig, max_error)
    pts = np.where(done[..., None], X, np.nan)
    err = np.where(done, mean_err, np.nan)
    views = items[3] & done[:, None]
    search = np.flatnonzero(~done[:, 0] & (items[3].sum((-1, -2)) >= 2))
    masks = _subset_masks(V)
    step = max(1, block * 32 // max(len(masks), 1))
    for s in range(0, len(search), step):
        idx = search[s : s + step]
        pts[idx], err[idx], views[idx] = _robust_block(
            *(a[idx] for a in items), rig, masks, max_error, keep_failed
        )
    n = int(np.prod(lead, dtype=int))
    return TriangulationResult(
        pts.reshape(*lead, J, 3),
        err.reshape(*lead, J),
        np.moveaxis(views.reshape(n, J, V), 1, 2).reshape(*lead, V, J),
    )


def recenter_point(points: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """Recentering translation of thesis 6.4.3.

    The weighted mean of the triangulated joints, each weighted by the minimum confidence
    over the views.

    Args:
        points: triangulated joints, shape (*, J, 3); NaN where missing.
        scores: confidences, shape (*, V, J).

    Returns:
        shape (*, 3); NaN when no joint was triangulated.
    """
    w = np.nan_to_num(np.asarray(scores, dtype=float)).min(axis=-2)  # (*, J)
    ok = np.isfinite(points).all(-1) & (w > 0)
    w = np.where(ok, w, 0.0)
    total = w.sum(-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = (np.nan_to_num(points) * w[..., None]).sum(-2) / total
    return np.where(total > 0, c, np.nan)
