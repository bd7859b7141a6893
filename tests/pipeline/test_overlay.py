"""Reprojection overlays (rmpl.pipeline.overlay) on tiny synthetic videos and image folders."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.poses import Poses3D

cv2 = pytest.importorskip("cv2")

from rmpl.pipeline.overlay import DETECTION_COLOR, PERSON_COLORS, write_overlays  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "src" / "rmpl" / "examples" / "walk"
W, H = 320, 240


def _scene(T: int = 3):
    """Two cameras around the example's walking person; frame 1 has no 3D person."""
    gt = np.load(EXAMPLE / "ground_truth.npz")["points"][:T, 0]  # (T, 17, 3)
    centre = np.nanmean(gt[0], axis=0)
    K = np.array([[260.0, 0, (W - 1) / 2], [0, 260, (H - 1) / 2], [0, 0, 1]])
    cams = []
    for v, a in enumerate((0.3, 1.9)):
        R, t = look_at(centre + [4 * np.cos(a), 4 * np.sin(a), 0.3], centre)
        cams.append(Camera(K, R, t, size=(W, H), name=f"cam{v}"))
    rig = Rig(tuple(cams))
    points = gt[:, None].copy()
    points[1] = np.nan
    poses = Poses3D(points, fps=25.0)
    kp = rig.project(gt)[:, :, None] + [6.0, -5.0]  # (T, V, 1, J, 2): "detections", offset
    scores = np.full(kp.shape[:-1], 0.9)
    kp[:, :, :, 9] = [12.0, 12.0]  # an undetected left wrist, put far away: not drawn
    scores[:, :, :, 9] = 0.0
    return rig, poses, kp, scores


def _green(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (g > 120) & (g > r + 50) & (g > b + 50)


def _magenta(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (r > 140) & (b > 140) & (g < r - 60)


def _near(mask: np.ndarray, uv: np.ndarray, radius: int = 1) -> bool:
    u, v = np.round(uv).astype(int)
    return bool(mask[v - radius : v + radius + 1, u - radius : u + radius + 1].any())


def _check_frames(frames: list[np.ndarray], rig: Rig, poses: Poses3D, kp, v: int) -> None:
    top = slice(0, int(0.65 * H))  # above the legend
    proj = rig[v].project(poses.points[0, 0])  # (J, 2)
    for a, b in ((5, 11), (11, 13), (6, 12)):  # shoulder-hip, hip-knee: long bones
        assert _near(_green(frames[0]), (proj[a] + proj[b]) / 2), (v, a, b)
    assert not _green(frames[1])[top].any()  # no 3D person in frame 1
    for j in (10, 15, 16):  # right wrist, ankles: detection dots
        assert _near(_magenta(frames[0]), kp[0, v, 0, j], 2), (v, j)
    assert not _magenta(frames[0])[:30, :30].any()  # the left wrist, score 0
    assert _magenta(frames[1])[top].any()  # detections drawn without a 3D person
    assert not _green(frames[2])[: H // 8, : W // 8].any()  # a corner stays background


def test_video_overlays(tmp_path):
    rig, poses, kp, scores = _scene()
    videos = []
    for v in range(len(rig)):
        path = tmp_path / f"in{v}.mp4"
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, (W, H))
        for _ in range(3):
            writer.write(np.full((H, W, 3), 40, np.uint8))
        writer.release()
        videos.append(path)
    out = tmp_path / "out"
    written = write_overlays(videos, poses, rig, out, kp, scores, progress=False)
    assert [p.name for p in written] == ["overlay_cam0.mp4", "overlay_cam1.mp4"]
    assert sorted(p.name for p in out.iterdir()) == ["overlay_cam0.mp4", "overlay_cam1.mp4"]
    for v, path in enumerate(written):
        cap = cv2.VideoCapture(str(path))
        frames = []
        while True:
            ok, im = cap.read()
            if not ok:
                break
            frames.append(cv2.cvtColor(im, cv2.COLOR_BGR2RGB))
        cap.release()
        assert len(frames) == 3 and frames[0].shape == (H, W, 3)
        _check_frames(frames, rig, poses, kp, v)


def test_image_overlays_replace_an_old_folder(tmp_path):
    rig, poses, kp, scores = _scene()
    folders = []
    for v in range(len(rig)):
        d = tmp_path / f"cam{v}"
        d.mkdir()
        for i in range(3):
            cv2.imwrite(str(d / f"f{i:03d}.jpg"), np.full((H, W, 3), 40, np.uint8))
        folders.append(d)
    out = tmp_path / "out"
    (out / "overlay_cam0").mkdir(parents=True)
    (out / "overlay_cam0" / "stale.png").write_bytes(b"old")
    write_overlays(folders, poses, rig, out, kp, scores, kind="images", progress=False)
    assert sorted(p.name for p in out.iterdir()) == ["overlay_cam0", "overlay_cam1"]
    for v in range(len(rig)):
        files = sorted((out / f"overlay_cam{v}").iterdir())
        assert [f.name for f in files] == ["f000.png", "f001.png", "f002.png"]
        frames = [cv2.cvtColor(cv2.imread(str(f)), cv2.COLOR_BGR2RGB) for f in files]
        _check_frames(frames, rig, poses, kp, v)
        # PNG is lossless: the exact colours are there.
        assert (frames[0] == PERSON_COLORS[0]).all(-1).any()
        assert (frames[0] == DETECTION_COLOR).all(-1).any()


def test_overlay_checks_its_input(tmp_path):
    rig, poses, kp, scores = _scene()
    with pytest.raises(ValueError, match="one input per camera"):
        write_overlays([tmp_path / "a.mp4"], poses, rig, tmp_path / "out", kp, scores)
    with pytest.raises(ValueError, match=r"\(T, 2, P, J, 2\)"):
        write_overlays(
            [tmp_path / "a.mp4"] * 2, poses, rig, tmp_path / "out", kp[:, :1], scores[:, :1]
        )
    assert not (tmp_path / "out").exists()
