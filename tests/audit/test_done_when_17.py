"""Audit of issue 17's "Done when" tests: what the existing people-axis tests left out.

The existing tests take a multi-person detector through ``detect_videos`` (stand-in) and
through ``rmpl run --videos`` only with one rendered person. Here a stand-in multi-person
detector goes through the whole ``rmpl run --videos`` path with two people (two tracks,
each where it stands), the same videos through a single-person detector give one track,
and a camera that sees nobody is named in a warning while the run goes on with the others.
Needs only OpenCV (no mediapipe, no rendering).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.calibration import save_rig
from rmpl.io.poses import load_poses
from rmpl.skeleton import COCO17

cv2 = pytest.importorskip("cv2")

T, V = 6, 3
SIZE = (320, 240)


class TwoPeople:
    """A stand-in multi-person detector (``max_people`` 3): an image's grey level codes its
    (frame, view); it returns the true projections of the people that view sees, in slots
    0 and 1, slot 2 empty. ``max_people = 1`` makes it a single-person one (slot 0 only)."""

    name = "two-people"
    skeleton = COCO17

    def __init__(self, pixels: np.ndarray, sees: np.ndarray, max_people: int = 3) -> None:
        self.pixels, self.sees = pixels, sees  # (T, V, P, J, 2), (V, P) bool
        self.max_people = max_people

    def reset(self) -> None:
        pass

    def close(self) -> None:
        pass

    def __call__(self, images):
        code = np.array([int(round(im.mean() / 10)) - 1 for im in images])
        t, v = code // V, code % V
        B, N, J = len(images), self.max_people, COCO17.num_joints
        kp, sc = np.full((B, N, J, 2), np.nan), np.zeros((B, N, J))
        for b in range(B):
            for p in range(min(N, 2)):
                if self.sees[v[b], p]:
                    kp[b, p], sc[b, p] = self.pixels[t[b], v[b], p], 0.9
        if N == 1:
            return kp[:, 0], sc[:, 0]  # the single-person protocol: (B, J, 2), (B, J)
        return kp, sc


def _scene(tmp_path: Path) -> tuple[Rig, np.ndarray, list[str]]:
    """Three cameras around two people 1.6 m apart; one grey video per camera."""
    K = np.array([[250.0, 0, SIZE[0] / 2], [0, 250, SIZE[1] / 2], [0, 0, 1]])
    cams = []
    for v in range(V):
        a = 2 * np.pi * v / V + 0.3
        R, t = look_at(np.array([6 * np.cos(a), 6 * np.sin(a), 1.8]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=SIZE, name=f"cam{v}"))
    rig = Rig(tuple(cams))
    rng = np.random.default_rng(0)
    body = rng.uniform(-0.25, 0.25, (17, 3)) + [0, 0, 1.0]
    X = np.stack([body + [-0.8 + 0.02 * f, 0, 0] for f in range(T)])  # person A
    X = np.stack([X, X + [1.6, 0.3, 0.0]], 1)  # (T, 2, 17, 3): A and B
    save_rig(rig, tmp_path / "calib.toml")
    videos = []
    for v in range(V):
        path = tmp_path / f"cam{v}.mp4"
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25, SIZE)
        for f in range(T):
            writer.write(np.full((SIZE[1], SIZE[0], 3), 10 * (f * V + v + 1), np.uint8))
        writer.release()
        videos.append(str(path))
    return rig, X, videos


def _run(tmp_path, monkeypatch, detector, name: str) -> Path:
    from rmpl.pipeline import detect2d

    monkeypatch.setitem(detect2d.DETECTORS, detector.name, lambda: detector)
    out = tmp_path / name
    argv = ["run", "--calib", str(tmp_path / "calib.toml"), "--videos", *detector.videos,
            "--out", str(out), "--detector", detector.name, "--method", "triangulate",
            "--filter", "none", "--formats", "npz", "--no-pictures"]  # fmt: skip
    assert main(argv) == 0
    return out


def _nearest(points: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Each true person's (P,) mean distance to its nearest track, metres."""
    d = np.nanmean(np.linalg.norm(points[:, :, None] - truth[:, None], axis=-1), axis=(0, 3))
    return d.min(0)


def test_a_multi_person_detector_through_rmpl_run_gives_two_tracks(tmp_path, monkeypatch):
    rig, X, videos = _scene(tmp_path)
    pixels = np.stack([c.project(X.reshape(-1, 3)).reshape(T, 2, 17, 2) for c in rig], 1)
    multi = TwoPeople(pixels, np.ones((V, 2), bool))
    multi.videos = videos
    poses = load_poses(_run(tmp_path, monkeypatch, multi, "multi") / "poses.npz")
    assert poses.points.shape[:2] == (T, 2)
    assert (_nearest(poses.points, X) < 1e-3).all()
    # The same videos through the single-person protocol: one person per view, one track.
    single = TwoPeople(pixels, np.ones((V, 2), bool), max_people=1)
    single.name, single.videos = "one-person", videos
    one = load_poses(_run(tmp_path, monkeypatch, single, "single") / "poses.npz")
    assert one.points.shape[:2] == (T, 1)
    assert np.nanmean(np.linalg.norm(one.points[:, 0] - X[:, 0], axis=-1)) < 1e-3


def test_a_camera_that_sees_nobody_is_named_and_the_run_goes_on(tmp_path, monkeypatch, caplog):
    rig, X, videos = _scene(tmp_path)
    pixels = np.stack([c.project(X.reshape(-1, 3)).reshape(T, 2, 17, 2) for c in rig], 1)
    sees = np.ones((V, 2), bool)
    sees[1] = False  # cam1 never finds anybody
    det = TwoPeople(pixels, sees)
    det.videos = videos
    with caplog.at_level(logging.WARNING):
        poses = load_poses(_run(tmp_path, monkeypatch, det, "out") / "poses.npz")
    warned = [r.getMessage() for r in caplog.records if "nobody was detected" in r.getMessage()]
    assert len(warned) == 1 and "cam1.mp4" in warned[0], warned
    assert poses.points.shape[:2] == (T, 2)
    assert (_nearest(poses.points, X) < 1e-3).all()  # cam0 and cam2 triangulate both
