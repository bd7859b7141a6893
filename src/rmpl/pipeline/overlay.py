"""Reprojection overlays: the 3D result drawn back onto the input videos or images.

For each camera, every input frame gets the 3D skeletons projected through that camera
(thick lines, one colour per person, lens distortion included) and the 2D detections the
3D result was made from (thin magenta lines and dots), so that a wrong calibration, a
mismatched view or a bad detection can be seen by eye. Videos give one ``overlay_<view>.mp4``
per camera (MPEG-4, the frame rate of the input); image folders give a folder
``overlay_<view>/`` of PNGs named like the input images. Every output is written
atomically: a video through a temporary file, a folder through a temporary folder that
replaces the old one at the end.

Needs OpenCV (``pip install 'rmpl[detect]'``).

Shape glossary: ``T`` frames, ``V`` views, ``P`` people, ``J`` joints.
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig
from rmpl.io.atomic import atomic_path
from rmpl.io.poses import Poses3D
from rmpl.skeleton import BY_COUNT, SKELETONS, Skeleton

__all__ = ["PERSON_COLORS", "DETECTION_COLOR", "draw_skeleton", "project_visible", "write_overlays"]

log = logging.getLogger(__name__)

#: RGB colours of the reprojected 3D people, in turn.
PERSON_COLORS = ((40, 220, 60), (250, 200, 30), (40, 200, 250), (250, 120, 30), (160, 90, 250))
#: RGB colour of the 2D detections.
DETECTION_COLOR = (240, 40, 240)


def project_visible(points: np.ndarray, camera: Camera) -> np.ndarray:
    """Project world points into a camera, NaN for missing points and points behind it.

    Args:
        points: world metres, shape (*, J, 3), NaN = missing.

    Returns:
        Pixels, shape (*, J, 2).

    >>> from rmpl.geometry.camera import look_at
    >>> R, t = look_at(np.array([0.0, -4, 1]), np.array([0.0, 0, 1]))
    >>> cam = Camera(np.array([[100.0, 0, 50], [0, 100, 40], [0, 0, 1]]), R, t)
    >>> project_visible(np.array([[0.0, 0, 1], [0, -5, 1]]), cam).round(1).tolist()
    [[50.0, 40.0], [nan, nan]]
    """
    X = np.asarray(points, dtype=float)
    depth = X @ camera.R[2] + camera.t[2]  # (*, J) metres along the optical axis
    with np.errstate(invalid="ignore"):
        uv = camera.project(np.where((depth > 1e-6)[..., None], X, np.nan))
    return uv


def draw_skeleton(
    image: np.ndarray,
    points: np.ndarray,
    skeleton: Skeleton,
    color: tuple[int, int, int],
    thickness: int = 2,
    radius: int = 0,
) -> np.ndarray:
    """Draw one 2D skeleton onto an image in place; joints with NaN pixels are left out.

    Args:
        image: RGB uint8, shape (H, W, 3).
        points: pixels, shape (J, 2).
        color: RGB.
        thickness: line width, pixels.
        radius: joint dot radius, pixels (0: no dots).

    Returns:
        ``image``.
    """
    import cv2

    h, w = image.shape[:2]
    limit = 4 * max(h, w)  # far outside: not drawn (and no integer overflow in OpenCV)
    ok = np.isfinite(points).all(-1) & (np.abs(points) < limit).all(-1)
    shift = 4  # sub-pixel line ends: 4 fractional bits
    pts = np.where(ok[:, None], points, 0) * (1 << shift)
    pts = np.round(pts).astype(np.int64)
    for a, b in skeleton.bones:
        if ok[a] and ok[b]:
            cv2.line(
                image, tuple(pts[a].tolist()), tuple(pts[b].tolist()), color, thickness,
                cv2.LINE_AA, shift,
            )  # fmt: skip
    if radius:
        for j in np.flatnonzero(ok):
            cv2.circle(
                image, tuple(pts[j].tolist()), radius << shift, color, -1, cv2.LINE_AA, shift
            )
    return image


def _legend(image: np.ndarray, scale: float) -> None:
    import cv2

    h = image.shape[0]
    y = h - int(8 * scale)
    for text, color in (("2D detection", DETECTION_COLOR), ("3D reprojected", PERSON_COLORS[0])):
        cv2.putText(
            image, text, (int(6 * scale), y), cv2.FONT_HERSHEY_SIMPLEX, 0.4 * scale, color,
            max(1, int(scale)), cv2.LINE_AA,
        )  # fmt: skip
        y -= int(16 * scale)


def _skeleton_2d(num_joints: int, skeleton: Skeleton) -> Skeleton:
    """The detections' joint set: the 3D's when the joint counts match, else COCO-17 for 17
    joints and HALPE-26 for 26; another count is drawn as dots only."""
    if num_joints == skeleton.num_joints:
        return skeleton
    if num_joints in BY_COUNT:
        return SKELETONS[BY_COUNT[num_joints]]
    return Skeleton("dots", tuple(f"joint_{j}" for j in range(num_joints)))


def _frame_rows(frames: np.ndarray, num_frames: int) -> np.ndarray:
    """Row of each input frame 0..num_frames-1 in ``frames``, -1 where absent."""
    rows = np.full(num_frames, -1)
    frames = np.asarray(frames).astype(int)
    inside = (frames >= 0) & (frames < num_frames)
    rows[frames[inside]] = np.flatnonzero(inside)
    return rows


def _annotate(
    image: np.ndarray,
    t: int,
    v: int,
    camera: Camera,
    poses: Poses3D,
    pose_rows: np.ndarray,
    keypoints: np.ndarray | None,
    scores: np.ndarray | None,
    kp_rows: np.ndarray | None,
    skeleton: Skeleton,
    skeleton_2d: Skeleton,
) -> np.ndarray:
    scale = max(1.0, min(image.shape[:2]) / 360)
    thick = max(1, round(2 * scale))
    if keypoints is not None and kp_rows[t] >= 0:
        for p in range(keypoints.shape[2]):
            kp = np.where(
                (scores[kp_rows[t], v, p] > 0)[:, None], keypoints[kp_rows[t], v, p], np.nan
            )
            draw_skeleton(image, kp, skeleton_2d, DETECTION_COLOR, max(1, thick // 2), thick + 1)
    if pose_rows[t] >= 0:
        uv = project_visible(poses.points[pose_rows[t]], camera)  # (P, J, 2)
        for p in range(uv.shape[0]):
            color = PERSON_COLORS[p % len(PERSON_COLORS)]
            draw_skeleton(image, uv[p], skeleton, color, thick + 1)
    _legend(image, scale)
    return image


def write_overlays(
    sources: Sequence[str | Path],
    poses: Poses3D,
    rig: Rig,
    out_dir: str | Path,
    keypoints: np.ndarray | None = None,
    scores: np.ndarray | None = None,
    frames: np.ndarray | None = None,
    kind: str = "videos",
    fps: float | None = None,
    progress: bool = True,
) -> list[Path]:
    """Draw the 3D result (and the 2D detections) onto each camera's input frames.

    Args:
        sources: one video (``kind="videos"``) or image folder (``kind="images"``) per
            camera, in the rig's order.
        poses: the 3D result; ``poses.frames`` are input frame numbers (0 = first frame).
        rig: the cameras, V of them.
        out_dir: where ``overlay_<camera>.mp4`` (or ``overlay_<camera>/``) go.
        keypoints: 2D detections, pixels, shape (T, V, P, J, 2), or None.
        scores: their confidences, shape (T, V, P, J); a detection with score 0 is not drawn.
        frames: input frame number of each row of ``keypoints``, shape (T,) (default 0..T-1).
        fps: frame rate of the overlay videos (default: the input videos').
        progress: show a progress bar per camera.

    Returns:
        The videos or folders written, one per camera.
    """

    from rmpl.pipeline.detect2d import (
        _cv2,
        _same_clock,
        check_image_folders,
        check_videos,
        image_frames,
        video_frames,
    )

    _cv2()  # a clear ImportError without OpenCV
    if kind not in ("videos", "images"):
        raise ValueError(f"kind must be 'videos' or 'images', got {kind!r}")
    if len(sources) != len(rig):
        raise InputError(None, "sources", f"one input per camera ({len(rig)})", len(sources))
    if keypoints is not None:
        keypoints, scores = _checked_keypoints(keypoints, scores, len(rig))
    skeleton = SKELETONS[poses.skeleton]  # the 3D's bones (COCO-17, or HALPE-26 with feet)
    skeleton_2d = skeleton if keypoints is None else _skeleton_2d(keypoints.shape[-2], skeleton)
    if kind == "videos":
        infos = check_videos(sources, synchronised=False)
        if not _same_clock(infos):
            log.warning("no overlays: the videos differ in length or frame rate")
            return []
        num_frames = infos[0].num_frames
        fps = fps or infos[0].fps
    else:
        files = check_image_folders(sources)
        num_frames = len(files[0])
    pose_rows = _frame_rows(poses.frames, num_frames)
    kp_rows = None
    if keypoints is not None:
        kp_frames = np.arange(len(keypoints)) if frames is None else np.asarray(frames)
        kp_rows = _frame_rows(kp_frames, num_frames)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for v, camera in enumerate(rig):
        stream = video_frames(infos[v]) if kind == "videos" else image_frames(files[v])
        args = (camera, poses, pose_rows, keypoints, scores, kp_rows, skeleton, skeleton_2d)
        target = (out_dir, fps) if kind == "videos" else (out_dir, files[v])
        written.append(_write_camera(stream, v, args, num_frames, target, progress))
    log.info("wrote reprojection overlays to %s", out_dir)
    return written


def _write_camera(stream, v: int, args, num_frames: int, target, progress: bool) -> Path:
    """One camera's overlay: a video when ``target`` is (folder, fps), else PNGs."""
    from tqdm import tqdm

    name = f"overlay_{args[0].name}"
    bar = tqdm(stream, total=num_frames, desc=name, unit="frame", disable=not progress)
    annotated = (_annotate(im, t, v, *args) for t, im in enumerate(bar))
    folder, extra = target
    if isinstance(extra, list):
        return _write_pngs(folder / name, annotated, extra)
    return _write_video(folder / f"{name}.mp4", annotated, extra)


def _checked_keypoints(keypoints, scores, num_views: int) -> tuple[np.ndarray, np.ndarray]:
    keypoints, scores = np.asarray(keypoints, float), np.asarray(scores, float)
    shape_ok = keypoints.ndim == 5 and keypoints.shape[1] == num_views
    if not shape_ok or scores.shape != keypoints.shape[:-1]:
        raise InputError(
            None, "keypoints", f"shape (T, {num_views}, P, J, 2) with scores (T, V, P, J)",
            f"{keypoints.shape} and {scores.shape}",
        )  # fmt: skip
    return keypoints, scores


def _write_video(path: Path, images: Iterator[np.ndarray], fps: float) -> Path:
    import cv2

    with atomic_path(path) as tmp:
        writer = None
        try:
            for im in images:
                if writer is None:
                    h, w = im.shape[:2]
                    fourcc = cv2.VideoWriter_fourcc(*"mp4v")
                    writer = cv2.VideoWriter(str(tmp), fourcc, float(fps), (w, h))
                    if not writer.isOpened():
                        raise OSError(f"OpenCV cannot write an MPEG-4 video to {path}")
                writer.write(cv2.cvtColor(im, cv2.COLOR_RGB2BGR))
        finally:
            if writer is not None:
                writer.release()
    return path


def _write_pngs(folder: Path, images: Iterator[np.ndarray], names: list[Path]) -> Path:
    import cv2

    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".part", dir=folder.parent))
    try:
        for im, src in zip(images, names, strict=True):
            if not cv2.imwrite(str(tmp / f"{src.stem}.png"), cv2.cvtColor(im, cv2.COLOR_RGB2BGR)):
                raise OSError(f"OpenCV cannot write {tmp / src.stem}.png")
        os.chmod(tmp, 0o777 & ~_umask())
        if folder.exists():
            shutil.rmtree(folder)
        os.replace(tmp, folder)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return folder


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
