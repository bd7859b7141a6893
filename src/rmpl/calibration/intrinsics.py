"""One camera's lens from its board views: OpenCV's pinhole model (k1, k2, p1, p2, k3) by
``cv2.calibrateCamera``, or its fisheye model (k1..k4) by ``cv2.fisheye.calibrate``.

Outlier images are dropped by a rule fixed in advance: after a calibration, an image whose
own reprojection RMS exceeds both 1 px and three times the median image's is dropped, and
the camera calibrated again without it (up to three rounds, never below
:data:`MIN_IMAGES`). The dropped images are named in the result.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rmpl.calibration.boards import Board
from rmpl.calibration.detect import Detection
from rmpl.errors import InputError

__all__ = ["MIN_IMAGES", "Intrinsics", "calibrate_intrinsics", "image_errors"]

#: Fewest images with the board that a camera's intrinsics are computed from.
MIN_IMAGES = 4
_DROP_PX, _DROP_RATIO, _ROUNDS = 1.0, 3.0, 3
_FAILED_PX = 3.0  # an RMS no sub-pixel corner detection explains: a failed fit


@dataclass
class Intrinsics:
    """One camera's lens.

    Attributes:
        K: (3, 3) pixels. dist: (5,) pinhole k1 k2 p1 p2 k3, or (4,) fisheye k1..k4.
        size: (width, height). fisheye: which model.
        rms: reprojection RMS of the images used, pixels.
        used, dropped: image names; errors: each used image's RMS, pixels.
        std: OpenCV's standard deviations of fx, fy, cx, cy, k1, k2, p1, p2, k3 (pinhole).
    """

    K: np.ndarray
    dist: np.ndarray
    size: tuple[int, int]
    fisheye: bool = False
    rms: float = float("nan")
    used: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    errors: list[float] = field(default_factory=list)
    std: np.ndarray | None = None


def _cv2():
    import cv2

    return cv2


def _calibrate(obj, img, size, fisheye: bool):
    cv2 = _cv2()
    if fisheye:
        flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
        obj = [o.reshape(-1, 1, 3) for o in obj]
        img = [i.reshape(-1, 1, 2) for i in img]
        criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-9)
        _, K, d, rv, tv = cv2.fisheye.calibrate(
            obj, img, size, None, None, flags=flags, criteria=criteria
        )
    else:
        obj32 = [o.astype(np.float32) for o in obj]
        img32 = [i.astype(np.float32) for i in img]
        out = cv2.calibrateCameraExtended(obj32, img32, size, None, None)
        if not out[0] < _FAILED_PX:  # the optimiser lost its way: start it from a homography
            guess = cv2.initCameraMatrix2D(obj32, img32, size)
            flags = cv2.CALIB_USE_INTRINSIC_GUESS
            retry = cv2.calibrateCameraExtended(obj32, img32, size, guess, None, flags=flags)
            out = retry if retry[0] < out[0] else out
        _, K, d, rv, tv, std = out[:6]
        return K, np.ravel(d), rv, tv, np.ravel(std)[:9]
    return K, np.ravel(d), rv, tv, np.full(8, np.nan)


def image_errors(obj, img, K, dist, rvecs, tvecs, fisheye: bool = False) -> np.ndarray:
    """Per image reprojection RMS, pixels."""
    cv2 = _cv2()
    out = []
    for o, i, r, t in zip(obj, img, rvecs, tvecs, strict=True):
        if fisheye:
            p = cv2.fisheye.projectPoints(o.reshape(-1, 1, 3), r, t, K, dist)[0]
        else:
            p = cv2.projectPoints(o, r, t, K, dist)[0]
        out.append(float(np.sqrt(np.mean(np.sum((p.reshape(-1, 2) - i) ** 2, axis=1)))))
    return np.array(out)


def calibrate_intrinsics(
    views: dict[str, Detection],
    board: Board,
    size: tuple[int, int],
    *,
    fisheye: bool = False,
    camera: str = "camera",
    source: str | None = None,
) -> Intrinsics:
    """Calibrate one camera from its board views.

    Args:
        views: image name -> the corners found in it.
        board: the board. size: image (width, height), pixels.
        fisheye: the fisheye model instead of the pinhole one.
        camera, source: named in errors.

    Raises:
        InputError: fewer than :data:`MIN_IMAGES` images with the board, or a calibration
            that OpenCV cannot make.
    """
    names = list(views)
    if len(names) < MIN_IMAGES:
        raise InputError(
            source, f"camera {camera}",
            f"the board in at least {MIN_IMAGES} images for its intrinsics "
            "(move it across the whole image, tilted)", f"{len(names)}",
        )  # fmt: skip
    pts = board.points
    obj = {n: pts[views[n].ids] for n in names}
    img = {n: views[n].corners for n in names}
    dropped: list[str] = []
    for round_ in range(_ROUNDS + 1):
        try:
            K, d, rv, tv, std = _calibrate(
                [obj[n] for n in names], [img[n] for n in names], size, fisheye
            )
        except Exception as e:  # cv2.error: a degenerate set of views
            raise InputError(
                source, f"camera {camera}", "board views OpenCV can calibrate from "
                "(tilt the board; fill the image)", str(e).strip().splitlines()[-1][:120],
            ) from None  # fmt: skip
        err = image_errors([obj[n] for n in names], [img[n] for n in names], K, d, rv, tv, fisheye)
        bad = (err > _DROP_PX) & (err > _DROP_RATIO * np.median(err))
        if round_ == _ROUNDS or not bad.any() or len(names) - bad.sum() < MIN_IMAGES:
            break
        dropped += [n for n, b in zip(names, bad, strict=True) if b]
        names = [n for n, b in zip(names, bad, strict=True) if not b]
    n_pts = np.array([len(img[n]) for n in names])
    rms = float(np.sqrt(np.sum(err**2 * n_pts) / n_pts.sum()))
    return Intrinsics(K, d, tuple(size), fisheye, rms, names, dropped, err.tolist(), std)
