"""A tiny calibrated scene for the bad-input corpus: 3 cameras (960 x 720), one person."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints


def make_rig(views: int = 3) -> Rig:
    K = np.array([[900.0, 0, 480], [0, 900, 360], [0, 0, 1]])
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views
        R, t = look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 2.0]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(960, 720), name=f"cam{v}"))
    return Rig(tuple(cams))


def make_scene(folder: Path, views: int = 3, frames: int = 8, names=None, seed: int = 0):
    """calib.toml + kp.json in ``folder``; returns the rig, the truth (T, J, 3), kp, scores."""
    rig = make_rig(views)
    rng = np.random.default_rng(seed)
    X = rng.uniform(-0.4, 0.4, (frames, 17, 3)) + [0, 0, 1]
    kp = rig.project(X)  # (T, V, J, 2)
    sc = np.full(kp.shape[:-1], 0.9)
    save_rig(rig, folder / "calib.toml")
    views_named = list(names) if names is not None else rig.names
    save_keypoints(
        Keypoints2D(kp[:, :, None], sc[:, :, None], "coco17", views_named, np.arange(frames), 30.0),
        folder / "kp.json",
    )
    return rig, X, kp, sc


def io_args(folder: Path, command: str = "triangulate", out: str = "out.json") -> list[str]:
    return [command, "--calib", str(folder / "calib.toml"), "--keypoints",
            str(folder / "kp.json"), "--out", str(folder / out)]  # fmt: skip
