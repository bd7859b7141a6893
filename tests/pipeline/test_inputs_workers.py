"""``rmpl run --detect-workers N`` reaches the detection of videos and images."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D
from rmpl.skeleton import COCO17

cv2 = pytest.importorskip("cv2")


def _rig_and_folders(tmp_path, views: int = 2):
    K = np.array([[200.0, 0, 80], [0, 200, 60], [0, 0, 1]])
    cams = []
    for v in range(views):
        R, t = look_at(np.array([4.0 * np.cos(v), 4.0 * np.sin(v), 1.5]), np.zeros(3))
        cams.append(Camera(K, R, t, size=(160, 120), name=f"cam{v}"))
    save_rig(Rig(tuple(cams)), tmp_path / "calib.toml")
    folders = []
    for v in range(views):
        d = tmp_path / f"cam{v}"
        d.mkdir()
        cv2.imwrite(str(d / "000.png"), np.zeros((120, 160, 3), np.uint8))
        folders.append(str(d))
    return folders


def test_detect_workers_is_passed_to_the_detection(tmp_path, monkeypatch):
    from rmpl.pipeline import detect2d

    seen = {}

    def fake_detect_images(sources, detector, *, fps=None, cache_dir=None, workers=1, **kw):
        seen["workers"] = workers
        T, V, J = 1, len(sources), COCO17.num_joints
        return Keypoints2D(np.full((T, V, 1, J, 2), np.nan), np.zeros((T, V, 1, J)), COCO17,
                           [f"cam{v}" for v in range(V)], np.arange(T), fps)  # fmt: skip

    monkeypatch.setattr(detect2d, "detect_images", fake_detect_images)
    folders = _rig_and_folders(tmp_path)
    argv = ["run", "--calib", str(tmp_path / "calib.toml"), "--images", *folders,
            "--fps", "25", "--out", str(tmp_path / "out"), "--detect-workers", "2",
            "--method", "triangulate"]  # fmt: skip
    main(argv)  # nobody is in these images: the run itself stops, the call was made
    assert seen["workers"] == 2


def test_detect_workers_below_one_is_one_clear_error(tmp_path, capsys):
    folders = _rig_and_folders(tmp_path)
    argv = ["run", "--calib", str(tmp_path / "calib.toml"), "--images", *folders, "--fps", "25",
            "--out", str(tmp_path / "out"), "--detect-workers", "0"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--detect-workers" in err[0] and "1 or more" in err[0]
    assert not (tmp_path / "out").exists()
