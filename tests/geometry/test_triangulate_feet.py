"""Triangulation of HALPE-26 2D: the feet, neck, head top and mid-hip are triangulated where
two views see them, and the COCO-17 joints come out as they do from COCO-17 2D."""

import numpy as np

from rmpl.geometry.triangulate import triangulate, triangulate_robust
from rmpl.skeleton import COCO17, HALPE26
from tests.geometry.test_camera import random_rig


def _scene(seed: int, views: int = 4, people: int = 3):
    rng = np.random.default_rng(seed)
    rig = random_rig(rng, views)
    X = rng.uniform(-0.6, 0.6, (people, 26, 3)) + [0, 0, 1]
    kp = rig.project(X) + rng.normal(0, 0.5, (people, views, 26, 2))
    sc = rng.uniform(0.4, 1.0, kp.shape[:-1])
    return rng, rig, X, kp, sc


def test_extra_joints_triangulated_where_two_views_see_them():
    _, rig, X, kp, sc = _scene(0)
    heel = HALPE26.index("left_heel")
    toe = HALPE26.index("right_big_toe")
    kp[:, 1:, heel], sc[:, 1:, heel] = np.nan, 0.0  # the left heel in one view only
    kp[:, 2:, toe], sc[:, 2:, toe] = np.nan, 0.0  # the right big toe in two
    for res in (
        triangulate(kp, sc, rig),
        triangulate_robust(kp, sc, rig, max_error=50.0),
    ):
        assert res.points.shape == (3, 26, 3)
        assert np.isnan(res.points[:, heel]).all()
        assert (res.num_views[:, toe] == 2).all()
        others = [j for j in range(17, 26) if j != heel]
        assert np.abs(res.points[:, others] - X[:, others]).max() < 0.02  # 0.5 px noise


def test_coco17_part_is_the_coco17_triangulation():
    _, rig, _, kp, sc = _scene(1, views=5)
    kp[0, 2, 5:11] = kp[0, 2, 5:11] + 80.0  # an outlier view on the arms
    dlt26, dlt17 = triangulate(kp, sc, rig), triangulate(kp[..., :17, :], sc[..., :17], rig)
    np.testing.assert_array_equal(dlt26.points[:, :17], dlt17.points)
    rob26 = triangulate_robust(kp, sc, rig, swap_pairs=HALPE26.flip_pairs)
    rob17 = triangulate_robust(kp[..., :17, :], sc[..., :17], rig, swap_pairs=COCO17.flip_pairs)
    np.testing.assert_array_equal(rob26.points[:, :17], rob17.points)
    np.testing.assert_array_equal(rob26.views[..., :17], rob17.views)


def test_swapped_heels_in_one_view_are_swapped_back():
    _, rig, X, kp, sc = _scene(2, views=4, people=1)
    left, right = HALPE26.index("left_heel"), HALPE26.index("right_heel")
    X[0, left], X[0, right] = [0.3, 0.0, 0.05], [-0.3, 0.0, 0.05]  # heels 60 cm apart
    kp = rig.project(X)
    kp[0, 1, [left, right]] = kp[0, 1, [right, left]]  # the detector confused them in view 1
    res = triangulate_robust(kp, sc, rig, max_error=5.0, swap_pairs=HALPE26.flip_pairs)
    assert np.abs(res.points[0, [left, right]] - X[0, [left, right]]).max() < 1e-6
    assert res.views[0, :, [left, right]].all()  # every view used, view 1 swapped back


def test_a_swap_never_invents_a_joint_seen_in_one_view():
    """A left heel seen in one view and a right heel seen in three: swapping the one view's
    left/right would make both 'triangulate', the left from a right-heel observation."""
    from rmpl.geometry.camera import Camera, Rig, look_at, project
    from rmpl.geometry.triangulate import triangulate_robust
    from rmpl.skeleton import HALPE26

    K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    eyes = [[3.0, 0, 1.5], [0, 3, 1.5], [-3, 0, 1.5], [0, -3, 1.5]]
    rig = Rig(tuple(Camera(K, *look_at(np.array(e), np.array([0, 0, 1.0])), name=str(i))
                    for i, e in enumerate(eyes)))  # fmt: skip
    X = np.random.default_rng(3).normal([0, 0, 1.0], 0.3, (26, 3))
    kp = np.stack([project(X, c.K, c.R, c.t) for c in rig.cameras])[None]  # (1, 4, 26, 2)
    sc = np.ones(kp.shape[:-1])
    lh, rh = HALPE26.index("left_heel"), HALPE26.index("right_heel")
    X[lh] = X[rh] + [0.04, 0.0, 0.0]  # feet together: a borrowed point fits within 15 px
    kp = np.stack([project(X, c.K, c.R, c.t) for c in rig.cameras])[None]
    sc[0, 1:, lh] = 0  # the left heel: view 0 only
    sc[0, 0, rh] = 0  # the right heel: views 1-3
    kp[sc == 0] = np.nan
    out = triangulate_robust(kp, sc, rig, swap_pairs=HALPE26.flip_pairs)
    assert np.isnan(out.points[0, lh]).all()
    np.testing.assert_allclose(out.points[0, rh], X[rh], atol=1e-6)
