"""``--check``: a camera turned after calibration is named; an intact rig is not."""

from __future__ import annotations

import numpy as np

from rmpl.calibration.boards import parse_board
from rmpl.calibration.check import check_calibration
from rmpl.calibration.render import make_scene
from rmpl.geometry.camera import Rig
from rmpl.io.keypoints import Keypoints2D


def _people(rig: Rig, seed: int = 0) -> Keypoints2D:
    rng = np.random.default_rng(seed)
    T, J = 30, 17
    X = rng.normal([0, 0, 1.0], [0.3, 0.3, 0.5], size=(T, J, 3))
    kp = np.stack([rig.project(X[t]) for t in range(T)])  # (T, V, J, 2)
    kp = kp + rng.normal(0, 1.0, kp.shape)
    return Keypoints2D(kp[:, :, None], np.ones(kp.shape[:3])[:, :, None], views=rig.names)


def test_a_turned_camera_is_named():
    import cv2

    rig = make_scene(parse_board("checkerboard:6x4:0.1"), cameras=4, intrinsics_views=0,
                     extrinsics_views=1).rig  # fmt: skip
    kp = _people(rig)
    assert not any(r["moved"] for r in check_calibration(kp, rig))
    cam = rig[2]
    turned = cv2.Rodrigues(np.array([0.0, 0.02, 0.0]))[0] @ cam.R
    turned_cam = cam.with_pose(turned, -turned @ cam.center)  # turned where it stands
    moved = Rig(tuple(c if i != 2 else turned_cam for i, c in enumerate(rig)))
    rows = check_calibration(kp, moved)
    assert [r["camera"] for r in rows if r["moved"]] == [cam.name]
