"""Tests of rmpl.data.base: the dataset type, projected stand-in keypoints, attaching 2D."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.data.base import (
    MultiViewDataset,
    attach_keypoints,
    coco17_by_name,
    keypoints_from_projection,
)
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.keypoints import Keypoints2D
from rmpl.skeleton import COCO17, H36M17


def _rig(size=(640, 480)) -> Rig:
    cams = []
    for i, x in enumerate((-3.0, 3.0)):
        R, t = look_at(np.array([x, -4.0, 1.5]), np.array([0, 0, 1.0]))
        K = [[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]
        cams.append(Camera(K, R, t, np.zeros(5), size, f"c{i}"))
    return Rig(tuple(cams))


def _dataset(T=3, P=2, skeleton="coco17", size=(640, 480), **kw) -> MultiViewDataset:
    rng = np.random.default_rng(0)
    J = 17
    gt = rng.uniform(-0.3, 0.3, (T, P, J, 3)) + np.array([0, 0, 1.0])
    gt[1, 1] = np.nan
    return MultiViewDataset(
        _rig(size), np.arange(10, 10 + T), gt, skeleton, None, None, "toy", **kw
    )


def test_validation_names_the_field():
    d = _dataset()
    assert len(d) == 3 and d.num_views == 2 and d.num_people == 2
    with pytest.raises(InputError, match="'gt'"):
        MultiViewDataset(d.rig, d.frames, d.gt[..., :2], "coco17", None, None, "x")
    with pytest.raises(InputError, match="'gt'"):
        MultiViewDataset(d.rig, d.frames, d.gt, "shelf14", None, None, "x")  # 17 != 14
    with pytest.raises(InputError, match="frames"):
        MultiViewDataset(d.rig, d.frames.astype(float), d.gt, "coco17", None, None, "x")
    kp = np.zeros((3, 2, 1, 17, 2))
    with pytest.raises(InputError, match="scores"):
        MultiViewDataset(d.rig, d.frames, d.gt, "coco17", kp, None, "x")
    with pytest.raises(InputError, match="keypoints"):
        MultiViewDataset(d.rig, d.frames, d.gt, "coco17", kp[:, :1], np.ones((3, 1, 1, 17)), "x")
    kp[0, 0, 0, 0] = np.nan
    with pytest.raises(InputError, match="scores.*0 where keypoints are NaN"):
        MultiViewDataset(d.rig, d.frames, d.gt, "coco17", kp, np.ones((3, 2, 1, 17)), "x")
    with pytest.raises(InputError, match="clips"):
        _dataset(clips=np.array(["a", "b"]))


def test_projection_without_noise_matches_the_rig():
    d = _dataset()
    k = keypoints_from_projection(d)
    assert k.keypoints.shape == (3, 2, 2, 17, 2) and k.scores.shape == (3, 2, 2, 17)
    expected = d.rig.project(d.gt.reshape(3, -1, 3)).reshape(3, 2, 2, 17, 2)
    np.testing.assert_allclose(k.keypoints[0], expected[0])
    assert np.isnan(k.keypoints[1, :, 1]).all() and np.all(k.scores[1, :, 1] == 0)
    assert np.all(k.scores[0] == 1) and d.keypoints is None  # a copy; the input unchanged


def test_projection_noise_outside_and_behind():
    d = _dataset(T=40, P=3)
    k = keypoints_from_projection(d, noise_px=2.0, rng=np.random.default_rng(1))
    clean = keypoints_from_projection(d)
    diff = (k.keypoints - clean.keypoints)[(k.scores > 0) & (clean.scores > 0)]
    assert 1.8 < diff.std() < 2.2 and abs(diff.mean()) < 0.2
    # Small images: joints fall outside and are missing; behind the camera too.
    small = keypoints_from_projection(_dataset(size=(330, 250)))
    inside = small.scores > 0
    assert 0 < inside.mean() < 1
    assert np.all((small.keypoints[inside] >= 0) & (small.keypoints[inside] <= [329, 249]))
    behind = _dataset()
    gt = behind.gt.copy()
    gt[0, 0] = [0.0, -10.0, 1.0]  # behind both cameras (they stand at y = -4, look to +y)
    k = keypoints_from_projection(
        MultiViewDataset(behind.rig, behind.frames, gt, "coco17", None, None, "b")
    )
    assert np.all(k.scores[0, :, 0] == 0) and np.isnan(k.keypoints[0, :, 0]).all()


def test_projection_maps_other_joint_sets_by_name():
    d = _dataset(skeleton="h36m17")
    k = keypoints_from_projection(d)
    idx = coco17_by_name(H36M17)
    assert np.all(k.scores[0][..., idx < 0] == 0)  # eyes, ears
    j = COCO17.index("left_knee")
    np.testing.assert_allclose(
        k.keypoints[0, 1, 0, j], d.rig[1].project(d.gt[0, 0, H36M17.index("left_knee")])
    )


def test_attach_keypoints_by_frame_and_view_name():
    d = _dataset()
    rng = np.random.default_rng(2)
    xy = rng.uniform(0, 600, (2, 2, 3, 17, 2))  # frames 11 and 99, views c1, c0
    kp = Keypoints2D(xy, np.full(xy.shape[:-1], 0.7), "coco17", ["c1", "c0"], np.array([11, 99]))
    out = attach_keypoints(d, kp)
    assert out.keypoints.shape == (3, 2, 3, 17, 2)
    np.testing.assert_allclose(out.keypoints[1, 0], xy[0, 1])  # frame 11, camera c0
    np.testing.assert_allclose(out.keypoints[1, 1], xy[0, 0])
    assert np.isnan(out.keypoints[[0, 2]]).all() and np.all(out.scores[[0, 2]] == 0)
    kp3 = Keypoints2D(xy[:, :1], np.ones((2, 1, 3, 17)), "coco17", ["x"], np.array([10, 11]))
    with pytest.raises(InputError, match="views"):
        attach_keypoints(d, kp3)
    clips = _dataset(clips=np.array(["a", "a", "b"]))
    with pytest.raises(InputError, match="single clip"):
        attach_keypoints(clips, kp)
