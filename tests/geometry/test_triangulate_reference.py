"""The fast triangulation against straightforward references kept here: the DLT solved for
every joint at once, and robust triangulation searching every subset of views joint by
joint. Random rigs, points, noise, outliers, missing views and left/right swaps; the
answers agree to 1e-6 m (the same views, errors and NaN)."""

import itertools

import numpy as np
import pytest

from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.geometry.rays import pixel_to_normalized
from rmpl.geometry.triangulate import (
    _dlt,
    _normalized_P,
    triangulate,
    triangulate_points,
    triangulate_robust,
)
from rmpl.skeleton import COCO17


def random_rig(rng, views: int, distortion: bool = False) -> Rig:
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views + rng.uniform(-0.3, 0.3)
        eye = np.array([4 * np.cos(a), 4 * np.sin(a), rng.uniform(1.5, 3.0)])
        f = rng.uniform(700, 1300)
        K = np.array([[f, 0, 640], [0, f * rng.uniform(0.98, 1.02), 480], [0, 0, 1]])
        dist = rng.normal(0, [0.05, 0.01, 1e-3, 1e-3, 0]) if distortion else np.zeros(5)
        R, t = look_at(eye, np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, dist=dist, size=(1280, 960), name=str(v)))
    return Rig(tuple(cams))


def random_2d(rng, rig: Rig, n: int, joints: int, outliers: float = 0.15, missing: float = 0.2):
    """Keypoints (n, V, J, 2) of random points with noise, outliers and missing entries."""
    X = rng.uniform(-0.6, 0.6, (n, joints, 3)) + [0, 0, 1.0]
    kp = rig.project(X) + rng.normal(0, 2.0, (n, len(rig), joints, 2))
    bad = rng.random(kp.shape[:-1]) < outliers
    kp[bad] += rng.normal(0, 60.0, (int(bad.sum()), 2))
    sc = rng.uniform(0.1, 1.0, kp.shape[:-1])
    gone = rng.random(sc.shape) < missing
    sc[gone] = 0.0
    kp[gone & (rng.random(sc.shape) < 0.5)] = np.nan
    return kp, sc


def reference_dlt(xy, P, w):
    """The DLT of every joint at once, all joints solved, then NaN below two views."""
    P = P[..., :, None, :, :]
    r0 = xy[..., 0:1] * P[..., 2, :] - P[..., 0, :]
    r1 = xy[..., 1:2] * P[..., 2, :] - P[..., 1, :]
    r0 = r0 / np.linalg.norm(r0, axis=-1, keepdims=True)
    r1 = r1 / np.linalg.norm(r1, axis=-1, keepdims=True)
    w2 = (w * w)[..., None, None]
    outer = r0[..., :, None] * r0[..., None, :] + r1[..., :, None] * r1[..., None, :]
    M = (w2 * outer).sum(axis=-4)
    h = np.linalg.eigh(M)[1][..., :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        X = h[..., :3] / h[..., 3:4]
    X[(w > 0).sum(axis=-2) < 2] = np.nan
    return X


def one_dlt(xy, P, w):
    """One joint: xy (k, 2), P (k, 3, 4), w (k,)."""
    M = np.zeros((4, 4))
    for (x, y), Pv, wv in zip(xy, P, w, strict=True):
        for r in (x * Pv[2] - Pv[0], y * Pv[2] - Pv[1]):
            r = r / np.linalg.norm(r)
            M += wv * wv * np.outer(r, r)
    h = np.linalg.eigh(M)[1][:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        return h[:3] / h[3]


def reference_swap(kp, sc, rig, pairs, min_score):
    """Per view, swap a left/right pair when that halves its error (full triangulations)."""
    kp, sc = kp.copy(), sc.copy()
    a_idx, b_idx = [a for a, _ in pairs], [b for _, b in pairs]
    for v in range(kp.shape[-3]):
        base = triangulate(kp, sc, rig, min_score).error
        base_err = base[..., a_idx] + base[..., b_idx]
        kp2, sc2 = kp.copy(), sc.copy()
        kp2[..., v, a_idx, :], kp2[..., v, b_idx, :] = kp[..., v, b_idx, :], kp[..., v, a_idx, :]
        sc2[..., v, a_idx], sc2[..., v, b_idx] = sc[..., v, b_idx], sc[..., v, a_idx]
        alt = triangulate(kp2, sc2, rig, min_score).error
        alt_err = alt[..., a_idx] + alt[..., b_idx]
        better = np.isfinite(base_err) & (np.nan_to_num(alt_err, nan=np.inf) < 0.5 * base_err)
        for k, (a, b) in enumerate(pairs):
            m = better[..., k]
            kp[m, v, a], kp[m, v, b] = kp2[m, v, a], kp2[m, v, b]
            sc[m, v, a], sc[m, v, b] = sc2[m, v, a], sc2[m, v, b]
    return kp, sc


def reference_robust(kp, sc, rig, min_score, max_error, pairs, keep_failed):
    """Every subset of the valid views of each joint, fewest exclusions first, then the
    lowest mean reprojection error within ``max_error``."""
    if pairs:
        kp, sc = reference_swap(kp, sc, rig, pairs, min_score)
    N, V, J = sc.shape
    P = _normalized_P(rig)
    pts, err, views = np.full((N, J, 3), np.nan), np.full((N, J), np.nan), np.zeros((N, V, J), bool)
    for n, j in itertools.product(range(N), range(J)):
        valid = np.isfinite(kp[n, :, j]).all(-1) & (sc[n, :, j] > 0) & (sc[n, :, j] >= min_score)
        best, fallback = None, None
        for k in range(2, V + 1):
            for c in itertools.combinations(range(V), k):
                c = list(c)
                if not valid[c].all():
                    continue
                xy = pixel_to_normalized(kp[n, c, j], rig.K[c], rig.dist[c])
                X = one_dlt(xy, P[c], sc[n, c, j])
                proj = rig.project(X[None])[:, 0]  # (V, 2)
                e = np.linalg.norm(proj[c] - kp[n, c, j], axis=-1).mean()
                if not (np.isfinite(X).all() and np.isfinite(e)):
                    continue
                key = (valid.sum() - k) * 1e6 + e
                if e <= max_error and (best is None or key < best[0]):
                    best = (key, X, e, c)
                if fallback is None or e < fallback[0]:
                    fallback = (e, X, e, c)
        pick = best or (fallback if keep_failed else None)
        if pick is not None:
            pts[n, j], err[n, j], views[n, pick[3], j] = pick[1], pick[2], True
    return pts, err, views


def same(a, b, tol=1e-6):
    assert np.array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_allclose(a[~np.isnan(a)], b[~np.isnan(b)], rtol=0, atol=tol)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dlt_matches_solving_every_joint(seed):
    rng = np.random.default_rng(seed)
    rig = random_rig(rng, views=4)
    kp, sc = random_2d(rng, rig, n=20, joints=6, missing=0.5)
    ok = np.isfinite(kp).all(-1) & (sc > 0)
    xy = pixel_to_normalized(np.where(ok[..., None], kp, 0.0), rig.K[:, None], rig.dist[:, None])
    w = np.where(ok, sc, 0.0)
    same(_dlt(xy, _normalized_P(rig), w), reference_dlt(xy, _normalized_P(rig), w))
    # a subset axis broadcast against the points, as the robust search uses it
    masks = rng.random((5, 4)) < 0.6
    ws = w[:, None] * masks[None, :, :, None]
    got = _dlt(xy[:, None], _normalized_P(rig), ws)
    same(got, reference_dlt(xy[:, None], _normalized_P(rig), ws))
    assert np.isnan(_dlt(xy, _normalized_P(rig), np.zeros_like(w))).all()


def test_triangulate_points_are_triangulates():
    rng = np.random.default_rng(3)
    rig = random_rig(rng, views=3, distortion=True)
    kp, sc = random_2d(rng, rig, n=15, joints=5)
    a = triangulate_points(kp, sc, rig, min_score=0.3)
    same(a, triangulate(kp, sc, rig, min_score=0.3).points, tol=0.0)


@pytest.mark.parametrize(
    ("seed", "views", "keep_failed", "swaps"),
    [(0, 3, False, False), (1, 4, False, True), (2, 4, True, True), (3, 5, True, False)],
)
def test_robust_matches_the_exhaustive_search(seed, views, keep_failed, swaps):
    rng = np.random.default_rng(seed)
    rig = random_rig(rng, views, distortion=seed % 2 == 1)
    kp, sc = random_2d(rng, rig, n=8, joints=17)
    pairs = COCO17.flip_pairs if swaps else None
    if swaps:  # left and right exchanged in some views
        for n, v in zip(*np.nonzero(rng.random((8, views)) < 0.3), strict=True):
            a, b = [p[0] for p in pairs], [p[1] for p in pairs]
            kp[n, v, a + b] = kp[n, v, b + a]
    got = triangulate_robust(kp, sc, rig, 0.3, 15.0, pairs, keep_failed)
    pts, err, views_used = reference_robust(kp, sc, rig, 0.3, 15.0, pairs, keep_failed)
    same(got.points, pts)
    same(got.error, err, tol=1e-6)
    assert np.array_equal(got.views, views_used)


def test_robust_keeps_leading_dims_and_empty_input():
    rng = np.random.default_rng(4)
    rig = random_rig(rng, views=3)
    kp, sc = random_2d(rng, rig, n=6, joints=4)
    flat = triangulate_robust(kp, sc, rig)
    shaped = triangulate_robust(kp.reshape(2, 3, 3, 4, 2), sc.reshape(2, 3, 3, 4), rig)
    same(shaped.points.reshape(6, 4, 3), flat.points, tol=0.0)
    assert np.array_equal(shaped.views.reshape(6, 3, 4), flat.views)
    one = triangulate_robust(kp[0], sc[0], rig)
    same(one.points, flat.points[0], tol=0.0)
    empty = triangulate_robust(kp[:0], sc[:0], rig)
    assert empty.points.shape == (0, 4, 3) and empty.views.shape == (0, 3, 4)
