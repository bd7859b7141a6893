import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from rmpl.geometry.triangulate import recenter_point, triangulate, triangulate_robust
from rmpl.skeleton import COCO17
from tests.geometry.test_camera import random_rig


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000))
def test_exact_projections_triangulate_to_1e6(seed):
    rng = np.random.default_rng(seed)
    rig = random_rig(rng, int(rng.integers(2, 6)), dist_scale=1.0)
    X = rng.uniform(-0.6, 0.6, (3, 17, 3)) + [0, 0, 1]
    kp = rig.project(X)
    scores = rng.uniform(0.2, 1.0, kp.shape[:-1])
    for res in (triangulate(kp, scores, rig), triangulate_robust(kp, scores, rig, min_score=0)):
        assert np.abs(res.points - X).max() < 1e-6
        assert np.nanmax(res.error) < 1e-3
        assert res.views.shape == (3, len(rig), 17)


def test_missing_views_and_too_few():
    rng = np.random.default_rng(0)
    rig = random_rig(rng, 3)
    X = rng.uniform(-0.5, 0.5, (17, 3)) + [0, 0, 1]
    kp = rig.project(X)
    scores = np.ones((3, 17))
    kp[0, :5] = np.nan  # joints 0-4 seen by views 1, 2 only
    scores[1:, 0] = 0  # joint 0 seen by no valid view at all
    res = triangulate(kp, scores, rig)
    assert np.isnan(res.points[0]).all()
    assert np.allclose(res.points[1:], X[1:], atol=1e-6)
    assert res.num_views[1] == 2 and res.num_views[6] == 3


def test_robust_beats_dlt_with_outlier_views():
    rng = np.random.default_rng(3)
    rig = random_rig(rng, 5)
    X = rng.uniform(-0.6, 0.6, (40, 17, 3)) + [0, 0, 1]
    kp = rig.project(X) + rng.normal(0, 1.0, (40, 5, 17, 2))
    scores = np.full(kp.shape[:-1], 0.9)
    bad = rng.random((40, 17)) < 0.5  # half of the joints get one wild view
    view = rng.integers(0, 5, (40, 17))
    f, j = np.nonzero(bad)
    kp[f, view[f, j], j] += rng.uniform(60, 150, (len(f), 2)) * rng.choice([-1, 1], (len(f), 2))
    plain = triangulate(kp, scores, rig)
    robust = triangulate_robust(kp, scores, rig)
    e_plain = np.linalg.norm(plain.points - X, axis=-1)[bad].mean()
    e_robust = np.linalg.norm(robust.points - X, axis=-1)[bad].mean()
    assert e_robust < 0.5 * e_plain
    # The excluded view is the corrupted one.
    used = robust.views[f, :, j]
    assert (~used[np.arange(len(f)), view[f, j]]).mean() > 0.95


def test_robust_fixes_left_right_swap():
    rng = np.random.default_rng(5)
    rig = random_rig(rng, 4)
    X = rng.uniform(-0.6, 0.6, (10, 17, 3)) + [0, 0, 1]
    kp = rig.project(X)
    swapped = kp.copy()
    perm = COCO17.flip_permutation()
    swapped[:, 1] = kp[:, 1][:, perm]
    scores = np.ones(kp.shape[:-1])
    res = triangulate_robust(swapped, scores, rig, swap_pairs=COCO17.flip_pairs)
    assert np.nanmax(np.abs(res.points - X)) < 1e-6
    assert res.views.all()


def test_recenter_point_weights_by_min_confidence():
    pts = np.array([[0.0, 0, 0], [2.0, 0, 0], [np.nan, np.nan, np.nan]])
    scores = np.array([[1.0, 0.5, 1.0], [0.5, 1.0, 1.0]])  # min over views: 0.5, 0.5, 1
    assert np.allclose(recenter_point(pts, scores), [1.0, 0, 0])
    assert np.isnan(recenter_point(pts[2:], scores[:, 2:])).all()
