"""Find a board's inner corners in an image with OpenCV's detectors.

Checkerboards go through ``cv2.findChessboardCornersSB`` (sub-pixel accurate), ChArUco
boards through ``cv2.aruco.CharucoDetector`` (OpenCV >= 4.7's API). Each image is tried as
it is and inverted, so a board printed white-on-black is found without a flag.

:func:`diagnose` says why a board was found in none of a camera's images: the inner
corner counts (a checkerboard given by its squares), another ArUco dictionary, an older
OpenCV's ChArUco layout, the columns and rows swapped, or blur.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rmpl.calibration.boards import DICTIONARIES, Board

__all__ = ["Detection", "detect", "diagnose", "sharpness", "to_gray"]


@dataclass(frozen=True)
class Detection:
    """The corners of one board found in one image.

    Attributes:
        ids: corner numbers, shape (n,), into ``Board.points``.
        corners: their pixels, shape (n, 2).
        inverted: found in the inverted image.
    """

    ids: np.ndarray
    corners: np.ndarray
    inverted: bool = False

    def __len__(self) -> int:
        return len(self.ids)


def _cv2():
    import cv2

    return cv2


def to_gray(image: np.ndarray) -> np.ndarray:
    """uint8 grey (H, W) from grey or RGB (H, W, 3)."""
    image = np.asarray(image)
    if image.ndim == 3:
        image = _cv2().cvtColor(image, _cv2().COLOR_RGB2GRAY)
    return np.ascontiguousarray(image, dtype=np.uint8)


def sharpness(gray: np.ndarray) -> float:
    """Variance of the Laplacian of a half-size image: higher is sharper."""
    cv2 = _cv2()
    small = cv2.resize(gray, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    return float(cv2.Laplacian(small, cv2.CV_64F).var())


def detect(image: np.ndarray, board: Board, *, thorough: bool = False) -> Detection | None:
    """The board's inner corners in one image, or None when too few are found.

    Args:
        image: grey (H, W) or RGB (H, W, 3) uint8.
        board: the printed board.
        thorough: a checkerboard not found at once is searched again exhaustively
            (``CALIB_CB_EXHAUSTIVE``, slower): for photos, where each one counts.

    Returns:
        The corners found (at least ``board.min_corners``, not all on one line), or None.
    """
    gray = to_gray(image)
    find = _find_checkerboard if board.kind == "checkerboard" else _find_charuco
    # a checkerboard's inverse is a checkerboard, which findChessboardCornersSB finds as is
    tries = (
        (board.inverted,) if board.kind == "checkerboard" else (board.inverted, not board.inverted)
    )
    for inverted in tries:
        g = 255 - gray if inverted else gray
        found = (
            _find_checkerboard(g, board, None, thorough)
            if board.kind == "checkerboard"
            else find(g, board)
        )
        if (
            found is not None and len(found[0]) >= board.min_corners and _spread(found[1])
            and _grid_like(board, *found)
        ):  # fmt: skip
            return Detection(found[0], found[1], inverted)
    return None


def _grid_like(board: Board, ids: np.ndarray, corners: np.ndarray) -> bool:
    """The corners fit the board through one homography to within a quarter of a square:
    a grid read in a wrong order (or a misread marker) does not, whatever the lens."""
    cv2 = _cv2()
    src = board.points[ids, :2].astype(np.float64)
    H, _ = cv2.findHomography(src, corners.astype(np.float64), 0)
    if H is None:
        return False
    p = cv2.perspectiveTransform(src.reshape(-1, 1, 2), H).reshape(-1, 2)
    err = float(np.sqrt(np.mean(np.sum((p - corners) ** 2, axis=1))))
    ref = cv2.perspectiveTransform((src + [board.square, 0]).reshape(-1, 1, 2), H).reshape(-1, 2)
    square_px = float(np.median(np.linalg.norm(ref - p, axis=1)))
    return err < 0.25 * square_px


def _spread(corners: np.ndarray) -> bool:
    """Corners that span an area (not one line): the smaller spread over 1 px."""
    c = corners - corners.mean(axis=0)
    return bool(np.sqrt(np.linalg.eigvalsh(c.T @ c / len(c))[0]) > 1.0)


def _find_checkerboard(gray: np.ndarray, board: Board, size=None, thorough: bool = False):
    cv2 = _cv2()
    size = size or board.inner
    ok, corners = cv2.findChessboardCornersSB(gray, size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok and thorough:
        flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE
        ok, corners = cv2.findChessboardCornersSB(gray, size, flags=flags)
    if not ok or corners is None:
        return None
    corners = _refine(gray, corners.reshape(-1, 2), size[0], 0.25)
    return np.arange(size[0] * size[1]), corners


def _refine(gray: np.ndarray, corners: np.ndarray, per_row: int | None, reach: float) -> np.ndarray:
    """Corners refined by ``cv2.cornerSubPix`` in a window ``reach`` times the spacing of
    neighbouring corners (2 to 7 px half-width)."""
    cv2 = _cv2()
    if per_row is not None and len(corners) > per_row:
        gaps = np.linalg.norm(np.diff(corners.reshape(-1, per_row, 2), axis=1), axis=-1)
        spacing = float(np.min(gaps))
    else:
        d = np.linalg.norm(corners[:, None] - corners[None], axis=-1)
        spacing = float(np.min(d + np.eye(len(d)) * 1e9)) if len(d) > 1 else 10.0
    win = int(np.clip(reach * spacing, 2, 7))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    pts = np.ascontiguousarray(corners, dtype=np.float32).reshape(-1, 1, 2)
    out = cv2.cornerSubPix(gray, pts, (win, win), (-1, -1), criteria)
    return out.reshape(-1, 2).astype(float)


_DETECTORS: dict = {}


def _charuco_detector(board: Board):
    key = (board.cols, board.rows, board.square, board.marker, board.dictionary, board.legacy)
    if key not in _DETECTORS:
        cv2 = _cv2()
        aruco = cv2.aruco
        dictionary = aruco.getPredefinedDictionary(getattr(aruco, board.dictionary))
        cv_board = aruco.CharucoBoard(
            (board.cols, board.rows), board.square, board.marker, dictionary
        )
        cv_board.setLegacyPattern(board.legacy)
        params = aruco.DetectorParameters()
        params.cornerRefinementMethod = aruco.CORNER_REFINE_SUBPIX
        charuco = aruco.CharucoParameters()
        charuco.minMarkers = 1
        _DETECTORS[key] = aruco.CharucoDetector(cv_board, charuco, params)
    return _DETECTORS[key]


def _find_charuco(gray: np.ndarray, board: Board):
    corners, ids, _, _ = _charuco_detector(board).detectBoard(gray)
    if ids is None or len(ids) == 0:
        return None
    ids = ids.ravel().astype(int)
    order = np.argsort(ids)
    # the window stays clear of the markers' corners, (square - marker) / 2 away diagonally
    reach = 0.8 * (1.0 - board.marker / board.square) / np.sqrt(2.0)
    return ids[order], _refine(gray, corners.reshape(-1, 2)[order], None, reach)


def _markers(gray: np.ndarray, dictionary: str) -> int:
    aruco = _cv2().aruco
    det = aruco.ArucoDetector(aruco.getPredefinedDictionary(getattr(aruco, dictionary)))
    best = 0
    for g in (gray, 255 - gray):
        _, ids, _ = det.detectMarkers(g)
        best = max(best, 0 if ids is None else len(ids))
    return best


def diagnose(images: list[np.ndarray], board: Board) -> str:
    """Why ``board`` is found in none of ``images`` (a few of a camera's), as advice."""
    grays = [to_gray(im) for im in images[:4]]
    if board.kind == "checkerboard":
        nx, ny = board.inner
        for size in ((nx - 1, ny - 1), (nx + 1, ny + 1)):
            for g in grays:
                if min(size) >= 2 and any(
                    _find_checkerboard(x, board, size) is not None for x in (g, 255 - g)
                ):
                    return (
                        f"a board with {size[0]}x{size[1]} inner corners is in the images: "
                        "--board checkerboard:COLSxROWS counts inner corners (squares - 1)"
                    )
    else:
        hint = _charuco_hint(grays, board)
        if hint:
            return hint
    sharp = float(np.median([sharpness(g) for g in grays])) if grays else 0.0
    if sharp < 20.0:
        return f"the images look blurred (sharpness {sharp:.0f}; sharp prints give over 100)"
    return "check the board's size, that it is fully in view, well lit and not blurred"


def _charuco_hint(grays: list[np.ndarray], board: Board) -> str | None:
    from dataclasses import replace

    own = max((_markers(g, board.dictionary) for g in grays), default=0)
    if own == 0:
        for name in DICTIONARIES:
            if name != board.dictionary and max(_markers(g, name) for g in grays[:2]) >= 2:
                return f"no {board.dictionary} marker found but {name} markers are: pass :{name}"
        return f"no {board.dictionary} marker found: check the dictionary and the marker size"
    for other, why in (
        (replace(board, legacy=not board.legacy), "a board drawn by OpenCV before 4.6"),
        (replace(board, cols=board.rows, rows=board.cols), "columns and rows swapped"),
    ):
        if any(_find_charuco(g, other) is not None for g in grays):
            return f"markers are found but the corners fit {why}: {other.cols}x{other.rows}"
    return f"{own} markers found but too few corners: check COLSxROWS (squares, not corners)"
