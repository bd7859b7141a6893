"""The view check, computed on the person-frames with 3D only, against the straightforward
check of every person-frame (kept here, with the DLT solved for every joint): random
scenes with views showing another person, left/right swaps, missing views and joints,
absent people. Statuses, swaps and verdicts are equal; errors and sizes agree to 1e-9."""

import numpy as np
import pytest

import rmpl.pipeline.consistency as C
from rmpl.geometry.rays import pixel_to_normalized
from rmpl.geometry.triangulate import _normalized_P
from rmpl.io.poses import ViewStatus
from rmpl.skeleton import COCO17
from tests.geometry.test_triangulate_reference import reference_dlt
from tests.pipeline.test_consistency import make_rig, standing


class _ReferenceErrors(C._Errors):
    def triangulate(self, views):
        w = np.where(views[..., None] & self.valid, self.sc, 0.0)
        ok = np.isfinite(self.kp).all(-1) & (w > 0)
        rig = self.rig
        xy = pixel_to_normalized(
            np.where(ok[..., None], self.kp, 0.0), rig.K[:, None], rig.dist[:, None]
        )
        return reference_dlt(xy, _normalized_P(rig), np.where(ok, w, 0.0))


def reference_check(points, keypoints, scores, rig, heights, config, mirror):
    """Every person-frame checked (COCO-17 input), absent ones marked at the end."""
    cfg = config
    thr = cfg.threshold
    present = ~np.isnan(points).all((-1, -2))
    size = C._sizes(points, keypoints, rig, heights)
    err = _ReferenceErrors(keypoints, scores, rig, size, cfg.min_joints)
    has2d = err.valid.any(-1) & present[..., None]

    class _Bar:
        def update(self):
            pass

    consensus, comparable = C._consensus(err, has2d, thr, _Bar())
    found = consensus.any(-1)
    error = np.full(has2d.shape, np.nan)
    flipped = np.full(has2d.shape, np.nan)
    mirrored = _ReferenceErrors(
        keypoints[..., mirror, :], scores[..., mirror], rig, size, cfg.min_joints
    )
    V = has2d.shape[-1]
    for v in range(V):
        others = consensus.copy()
        others[..., v] = False
        everyone = has2d.copy()
        everyone[..., v] = False
        n, m = others.sum(-1, keepdims=True), everyone.sum(-1, keepdims=True)
        fallback = np.where(m >= 2, everyone, has2d)
        ref = np.where(n >= 2, others, np.where(found[..., None], consensus, fallback))
        X = err.triangulate(ref)
        error[..., v] = err(X)[..., v]
        flipped[..., v] = mirrored(X)[..., v]
    error = np.where(has2d, error, np.nan)
    status = np.full(has2d.shape, int(ViewStatus.UNCHECKED), np.uint8)
    checked = np.isfinite(error)
    status[checked & (error <= thr)] = ViewStatus.AGREES
    status[checked & (error > thr)] = ViewStatus.DISAGREES
    enough = err.valid.sum(-1) >= cfg.min_joints
    status[has2d & enough & ~found[..., None] & comparable[..., None]] = ViewStatus.DISAGREES
    inside = C._in_image(points, rig)
    status[~has2d & inside] = ViewStatus.MISSED
    status[~has2d & ~inside] = ViewStatus.OUT_OF_VIEW
    status[~present] = ViewStatus.ABSENT
    agrees = (status == ViewStatus.AGREES).sum(-1)
    disagrees = (status == ViewStatus.DISAGREES).sum(-1)
    compared = agrees + disagrees >= 2
    contested = compared & (disagrees >= 1)
    n_compared = compared.sum(0)
    failed = (n_compared > 0) & (contested.sum(0) > cfg.most_frames * n_compared)
    swapped = (status == ViewStatus.DISAGREES) & (flipped <= np.minimum(thr, 0.5 * error))
    return status, error, size, compared, contested, failed, swapped


def random_scene(seed, T=24, P=3, views=4):
    """People walking about; each view's 2D of a person is theirs, another's, mirrored,
    missing, or thinned; some people are absent in some frames."""
    rng = np.random.default_rng(seed)
    rig = make_rig(views)
    heights = rng.uniform(1.5, 1.9, P)
    pos = rng.uniform(-1.2, 1.2, (P, 2)) + np.linspace(0, 0.6, T)[:, None, None]
    X = (
        np.stack([standing(h) for h in heights])[None]
        + np.concatenate([pos, np.zeros((T, P, 1))], -1)[:, :, None]
    )
    X = X + rng.normal(0, 0.01, X.shape)
    proj = rig.project(X.reshape(T, -1, 3)).reshape(T, views, P, 17, 2).transpose(0, 2, 1, 3, 4)
    kp = proj + rng.normal(0, 1.5, proj.shape)
    other = rng.random((T, P, views)) < 0.12
    shift = rng.integers(1, P, (T, P, views))
    for t, p, v in zip(*np.nonzero(other), strict=True):
        kp[t, p, v] = proj[t, (p + shift[t, p, v]) % P, v]
    flip = rng.random((T, P, views)) < 0.1
    kp[flip] = kp[flip][:, COCO17.flip_permutation()]
    sc = rng.uniform(0.3, 1.0, kp.shape[:-1])
    sc[rng.random(sc.shape) < 0.15] = 0.0
    sc[rng.random((T, P, views)) < 0.15] = 0.0  # the view missed the person
    kp[sc == 0] = np.nan
    points = X.copy()
    points[rng.random((T, P)) < 0.3] = np.nan  # absent
    points[rng.random((T, P, 17)) < 0.1] = np.nan
    heights[0] = np.nan
    return points, kp, sc, rig, heights


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_check_views_matches_checking_every_person_frame(seed):
    points, kp, sc, rig, heights = random_scene(seed)
    cfg = C.ConsistencyConfig()
    mirror = COCO17.flip_permutation()
    got = C.check_views(points, kp, sc, rig, heights, cfg, mirror)
    status, error, size, compared, contested, failed, swapped = reference_check(
        points, kp, sc, rig, heights, cfg, mirror
    )
    assert (status == ViewStatus.DISAGREES).any() and (status == ViewStatus.ABSENT).any()
    assert np.array_equal(got.status, status)
    assert np.array_equal(np.isnan(got.error), np.isnan(error))
    np.testing.assert_allclose(got.error, error, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.size, size, rtol=0, atol=1e-9)
    assert np.array_equal(got.compared, compared) and np.array_equal(got.contested, contested)
    assert np.array_equal(got.failed, failed) and np.array_equal(got.swapped, swapped)


def test_check_views_with_nobody_present():
    points, kp, sc, rig, heights = random_scene(5, T=4)
    points[:] = np.nan
    got = C.check_views(points, kp, sc, rig, heights, mirror=COCO17.flip_permutation())
    assert (got.status == ViewStatus.ABSENT).all() and not got.failed.any()
    assert np.isnan(got.error).all() and not got.swapped.any()
