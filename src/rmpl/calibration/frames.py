"""The board views of each camera, from a folder of images or one video.

A folder: every image, in natural name order, image ``i`` being instant ``i``. A video:
frame ``i`` is instant ``i``; at most ``max_candidates`` frames, evenly spaced, are
decoded and searched (a tqdm bar shows it). For intrinsics, :func:`select_views` then keeps
up to ``max_views`` of the views found by a rule fixed in advance: views blurred to under
half the camera's median sharpness are left out; then, greedily, the view whose board adds
the most image cells (a 12 x 12 grid) not yet covered, ties (and views adding none) by
sharpness.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rmpl.calibration.boards import Board
from rmpl.calibration.detect import Detection, detect, diagnose, sharpness, to_gray
from rmpl.errors import InputError
from rmpl.pipeline.detect2d import IMAGE_SUFFIXES, list_images, probe_video, view_names

__all__ = ["CameraViews", "coverage", "read_views", "select_views", "source_names"]

GRID = 12


@dataclass
class CameraViews:
    """The board views of one camera.

    Attributes:
        name: the camera (from the folder or file name). source: the folder or video.
        size: image (width, height). labels: instant -> image file name or "frame N".
        views: instant -> the corners found. sharp: instant -> sharpness of that image.
        searched: how many images were searched.
    """

    name: str
    source: Path
    size: tuple[int, int]
    labels: dict[int, str] = field(default_factory=dict)
    views: dict[int, Detection] = field(default_factory=dict)
    sharp: dict[int, float] = field(default_factory=dict)
    searched: int = 0

    def named(self, keys=None) -> dict[str, Detection]:
        return {self.labels[k]: self.views[k] for k in (self.views if keys is None else keys)}


def source_names(paths: list[str | Path]) -> list[str]:
    """Camera names, as ``rmpl run --videos`` names views: file or folder names."""
    return view_names([Path(p) for p in paths])


def _cv2():
    import cv2

    return cv2


def _images(path: Path, max_candidates: int):
    files = list_images(path)
    yield len(files)
    for i, f in enumerate(files):
        image = _cv2().imread(str(f), _cv2().IMREAD_GRAYSCALE)
        if image is None:
            raise InputError(f, None, "an image file OpenCV can read", "unreadable")
        yield i, f.name, image


def _video(path: Path, max_candidates: int):
    info = probe_video(path)
    step = max(1, int(np.ceil(info.num_frames / max_candidates)))
    wanted = set(range(0, info.num_frames, step))
    yield len(wanted)
    cap = _cv2().VideoCapture(str(path))
    try:
        for i in range(info.num_frames):
            if not cap.grab():
                if i == 0:
                    raise InputError(path, None, "a video OpenCV can decode", "no frame")
                break
            if i in wanted:
                ok, frame = cap.retrieve()
                if ok:
                    yield i, f"frame {i}", to_gray(frame[..., ::-1])
    finally:
        cap.release()


def read_views(
    path: str | Path,
    board: Board,
    name: str,
    *,
    max_candidates: int = 300,
    progress: bool = True,
) -> CameraViews:
    """Search a camera's images (a folder) or frames (a video) for the board.

    Raises:
        InputError: no such file or folder, an unreadable image or video, images of
            different sizes, or the board in none of them (with advice, see
            :func:`rmpl.calibration.detect.diagnose`).
    """
    from tqdm.auto import tqdm

    path = Path(path)
    if not path.exists():
        raise InputError(
            path, f"camera {name}", "an existing folder of images or a video", "no such path"
        )
    frames = _images(path, max_candidates) if path.is_dir() else _video(path, max_candidates)
    total = next(frames)
    out: CameraViews | None = None
    samples: list[np.ndarray] = []
    with tqdm(
        total=total, desc=f"board {name}", unit="img", disable=not progress, leave=False
    ) as bar:
        for i, label, gray in frames:
            size = (gray.shape[1], gray.shape[0])
            out = out or CameraViews(name, path, size)
            if size != out.size:
                raise InputError(path / label if path.is_dir() else path, "size",
                                 f"{out.size[0]}x{out.size[1]} like the camera's other images",
                                 f"{size[0]}x{size[1]}")  # fmt: skip
            found = detect(gray, board, thorough=path.is_dir())
            out.labels[i], out.searched = label, out.searched + 1
            out.sharp[i] = sharpness(gray)
            if found is not None:
                out.views[i] = found
            elif len(samples) < 4:
                samples.append(gray)
            bar.update(1)
    if out is None:
        raise InputError(path, None, f"images ({', '.join(IMAGE_SUFFIXES)}) or a video", "none")
    if not out.views:
        raise InputError(path, f"camera {name}",
                         f"the board ({board.describe()}) in at least one image",
                         f"none of {out.searched}: {diagnose(samples, board)}")  # fmt: skip
    return out


def coverage(corners: np.ndarray, size: tuple[int, int], grid: int = GRID) -> np.ndarray:
    """Image cells (grid x grid, bool) under the convex hull of the corners (n, 2)."""
    cv2 = _cv2()
    mask = np.zeros((grid, grid), np.uint8)
    scale = np.array([grid / size[0], grid / size[1]])
    hull = cv2.convexHull((corners * scale * 16).astype(np.int32))
    cv2.fillConvexPoly(mask, hull, 1, shift=4)
    return mask.astype(bool)


def select_views(cam: CameraViews, max_views: int) -> list[int]:
    """The instants whose views calibrate the lens (see the module's rule)."""
    keys = sorted(cam.views)
    if len(keys) <= max_views:
        return keys
    median = np.median([cam.sharp[k] for k in keys])
    keys = [k for k in keys if cam.sharp[k] >= 0.5 * median] or keys
    cells = {k: coverage(cam.views[k].corners, cam.size) for k in keys}
    covered = np.zeros((GRID, GRID), bool)
    chosen: list[int] = []
    while len(chosen) < min(max_views, len(keys)):
        left = [k for k in keys if k not in chosen]
        best = max(left, key=lambda k: (int((cells[k] & ~covered).sum()), cam.sharp[k]))
        chosen.append(best)
        covered |= cells[best]
    return sorted(chosen)
