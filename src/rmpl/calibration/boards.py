"""Calibration boards: what was printed, parsed from ``--board`` or a board description file.

Two kinds:

- a checkerboard, ``checkerboard:COLSxROWS:SQUARE``: COLS x ROWS *inner* corners (where
  four squares meet), squares SQUARE metres wide;
- a ChArUco board, ``charuco:COLSxROWS:SQUARE:MARKER[:DICT]``: COLS x ROWS *squares*,
  squares SQUARE metres, markers MARKER metres, an OpenCV ArUco dictionary name
  (default ``DICT_4X4_50``). Its inner corners are (COLS-1) x (ROWS-1).

Board description files (``--board FILE.toml``), read by their keys:

- caliscope's ``charuco.toml``: ``columns``, ``rows``, ``dictionary``, ``aruco_scale``
  (marker / square), ``square_size_override_cm`` (or ``board_width`` / ``board_height`` in
  ``units``), ``inverted``;
- anipose's ``config.toml`` (its ``[calibration]`` table): ``board_type``, ``board_size``,
  ``board_square_side_length``, ``board_marker_length``, ``board_marker_bits``,
  ``board_marker_dict_number``. anipose measures the board in the unit its calibration is
  written in (often mm): lengths over 1 are read as millimetres, others as metres;
- Pose2Sim's ``Config.toml``: ``[calibration.calculate.intrinsics]``
  ``intrinsics_corners_nb`` (inner corners) and ``intrinsics_square_size`` (mm).

Object points: inner corner ``i`` of the board lies at ``Board.points[i]`` (metres, z = 0),
corner 0 at the origin, x along the first row, y along the first column. Corners are
numbered row by row as OpenCV numbers them.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError

__all__ = ["Board", "DICTIONARIES", "parse_board"]

#: ArUco dictionary names OpenCV knows, by name (a number each).
DICTIONARIES = (
    [f"DICT_{b}X{b}_{n}" for b in (4, 5, 6, 7) for n in (50, 100, 250, 1000)]
    + ["DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_16h5", "DICT_APRILTAG_25h9"]
    + ["DICT_APRILTAG_36h10", "DICT_APRILTAG_36h11", "DICT_ARUCO_MIP_36h12"]
)

_SPEC_HELP = (
    "checkerboard:COLSxROWS:SQUARE (inner corners, metres), "
    "charuco:COLSxROWS:SQUARE:MARKER[:DICT] (squares, metres), or a board .toml file"
)


@dataclass(frozen=True)
class Board:
    """One printed board.

    Attributes:
        kind: "checkerboard" or "charuco".
        cols, rows: inner corners (checkerboard) or squares (charuco) along x and y.
        square: square side, metres.
        marker: ChArUco marker side, metres (None for a checkerboard).
        dictionary: ChArUco ArUco dictionary name.
        legacy: ChArUco boards drawn by OpenCV before 4.6 with an even number of rows.
        inverted: printed white-on-black (a hint only: both are always tried).
    """

    kind: str
    cols: int
    rows: int
    square: float
    marker: float | None = None
    dictionary: str = "DICT_4X4_50"
    legacy: bool = False
    inverted: bool = False

    def __post_init__(self) -> None:
        if self.kind not in ("checkerboard", "charuco"):
            raise ValueError(f"unknown board kind {self.kind!r}")

    @property
    def inner(self) -> tuple[int, int]:
        """Inner corners along x and y."""
        if self.kind == "checkerboard":
            return self.cols, self.rows
        return self.cols - 1, self.rows - 1

    @property
    def num_corners(self) -> int:
        return self.inner[0] * self.inner[1]

    @property
    def points(self) -> np.ndarray:
        """Inner corners on the board, shape (N, 3), metres, corner 0 at the origin."""
        nx, ny = self.inner
        y, x = np.mgrid[0:ny, 0:nx]
        xy = np.stack([x.ravel(), y.ravel()], axis=1) * self.square
        return np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)

    @property
    def min_corners(self) -> int:
        """Fewest corners of one view worth keeping: 6, or the whole checkerboard."""
        return self.num_corners if self.kind == "checkerboard" else min(6, self.num_corners)

    def flipped_ids(self) -> np.ndarray:
        """Corner i seen from the board turned 180 degrees in its plane: N - 1 - i."""
        return np.arange(self.num_corners)[::-1].copy()

    def describe(self) -> str:
        if self.kind == "checkerboard":
            return f"checkerboard {self.cols}x{self.rows} inner corners, {self.square * 1000:g} mm"
        return (
            f"ChArUco {self.cols}x{self.rows} squares, {self.square * 1000:g} mm squares, "
            f"{self.marker * 1000:g} mm markers, {self.dictionary}"
        )

    def spec(self) -> str:
        """The ``--board`` text for this board."""
        size = f"{self.cols}x{self.rows}"
        if self.kind == "checkerboard":
            return f"checkerboard:{size}:{self.square:g}"
        return f"charuco:{size}:{self.square:g}:{self.marker:g}:{self.dictionary}"


def parse_board(text: str) -> Board:
    """A board from ``--board``: a spec string or a board description ``.toml`` file.

    >>> parse_board("checkerboard:4x7:0.06").num_corners
    28
    >>> parse_board("charuco:5x7:0.04:0.03").inner
    (4, 6)

    Raises:
        InputError: the spec does not parse, or the file lacks what a board needs.
    """
    if text.lower().endswith(".toml") or Path(text).is_file():
        return _board_file(Path(text))
    parts = text.split(":")
    kind = parts[0].lower()
    if kind in ("checkerboard", "chessboard") and len(parts) == 3:
        cols, rows = _size(text, parts[1])
        return _checked(text, Board("checkerboard", cols, rows, _length(text, parts[2])))
    if kind == "charuco" and len(parts) in (4, 5):
        cols, rows = _size(text, parts[1])
        dictionary = _dictionary(text, parts[4] if len(parts) == 5 else "DICT_4X4_50")
        square, marker = _length(text, parts[2]), _length(text, parts[3])
        return _checked(text, Board("charuco", cols, rows, square, marker, dictionary))
    raise InputError(None, "--board", _SPEC_HELP, text)


def _size(text: str, part: str) -> tuple[int, int]:
    m = re.fullmatch(r"(\d+)[xX](\d+)", part.strip())
    if not m:
        raise InputError(None, "--board", f"COLSxROWS such as 4x7 in {_SPEC_HELP}", text)
    return int(m.group(1)), int(m.group(2))


def _length(text: str, part: str) -> float:
    try:
        value = float(part)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value) or value <= 0:
        raise InputError(None, "--board", "a positive length in metres (0.06 for 60 mm)", text)
    if value > 1.0:
        raise InputError(
            None, "--board", "lengths in metres (0.06 for 60 mm, not 60)", f"{part} in {text}"
        )
    return value


def _dictionary(where: str | Path, name: str) -> str:
    wanted = str(name).strip()
    for known in DICTIONARIES:
        if known.lower() == wanted.lower():
            return known
    raise InputError(None if isinstance(where, str) else where, "dictionary",
                     f"an OpenCV ArUco dictionary, one of {', '.join(DICTIONARIES[:16])}, ...",
                     name)  # fmt: skip


def _checked(where: str | Path, board: Board) -> Board:
    path = None if isinstance(where, str) else where
    field = "--board" if path is None else "board"
    nx, ny = board.inner
    if nx < 2 or ny < 2:
        raise InputError(
            path, field, "at least 2x2 inner corners (a ChArUco board: at least 3x3 squares)",
            f"{board.cols}x{board.rows}",
        )  # fmt: skip
    if board.marker is not None and board.marker >= board.square:
        raise InputError(path, field, "a marker smaller than its square", board.describe())
    return board


def _board_file(path: Path) -> Board:
    if not path.is_file():
        raise InputError(
            path, "--board", f"an existing board file, or {_SPEC_HELP}", "no such file"
        )
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise InputError(path, None, "a TOML board description", str(e)) from None
    if isinstance(doc.get("charuco"), dict):
        doc = doc["charuco"]
    if "columns" in doc and "rows" in doc:
        return _checked(path, _caliscope(path, doc))
    calib = doc.get("calibration")
    if isinstance(calib, dict) and "board_type" in calib:
        return _checked(path, _anipose(path, calib))
    if isinstance(calib, dict) and isinstance(calib.get("calculate"), dict):
        intr = calib["calculate"].get("intrinsics", {})
        if "intrinsics_corners_nb" in intr:
            cols, rows = _pair(path, "intrinsics_corners_nb", intr["intrinsics_corners_nb"])
            square = _number(path, "intrinsics_square_size", intr.get("intrinsics_square_size"))
            return _checked(path, Board("checkerboard", cols, rows, square / 1000.0))
    raise InputError(
        path, None,
        "a caliscope charuco.toml (columns, rows), an anipose config ([calibration] board_type)"
        " or a Pose2Sim Config.toml (intrinsics_corners_nb)",
        f"keys {sorted(doc)[:8]}",
    )  # fmt: skip


def _number(path: Path, key: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise InputError(path, key, "a positive number", value)
    return float(value)


def _pair(path: Path, key: str, value: object) -> tuple[int, int]:
    if not (isinstance(value, list) and len(value) == 2 and all(isinstance(v, int) for v in value)):
        raise InputError(path, key, "two whole numbers [COLS, ROWS]", value)
    return int(value[0]), int(value[1])


def _caliscope(path: Path, doc: dict) -> Board:
    cols = int(_number(path, "columns", doc.get("columns")))
    rows = int(_number(path, "rows", doc.get("rows")))
    scale = _number(path, "aruco_scale", doc.get("aruco_scale", 0.75))
    if "square_size_override_cm" in doc:
        square = _number(path, "square_size_override_cm", doc["square_size_override_cm"]) / 100
    else:
        unit = {"inch": 0.0254, "cm": 0.01, "mm": 0.001, "m": 1.0}.get(doc.get("units", "inch"))
        if unit is None:
            raise InputError(path, "units", "inch, cm, mm or m", doc.get("units"))
        width = _number(path, "board_width", doc.get("board_width")) * unit
        height = _number(path, "board_height", doc.get("board_height")) * unit
        square = min(width / cols, height / rows)
    dictionary = _dictionary(path, doc.get("dictionary", "DICT_4X4_50"))
    inverted = bool(doc.get("inverted", False))
    return Board("charuco", cols, rows, square, square * scale, dictionary, inverted=inverted)


def _anipose(path: Path, calib: dict) -> Board:
    kind = str(calib["board_type"]).lower()
    cols, rows = _pair(path, "board_size", calib.get("board_size"))
    square = _mm_or_m(
        _number(path, "board_square_side_length", calib.get("board_square_side_length"))
    )
    if kind == "checkerboard":
        return Board("checkerboard", cols, rows, square)
    if kind != "charuco":
        raise InputError(path, "board_type", "charuco or checkerboard", calib["board_type"])
    marker = _mm_or_m(_number(path, "board_marker_length", calib.get("board_marker_length")))
    bits = int(calib.get("board_marker_bits", 4))
    number = int(calib.get("board_marker_dict_number", 50))
    return Board(
        "charuco", cols, rows, square, marker, _dictionary(path, f"DICT_{bits}X{bits}_{number}")
    )


def _mm_or_m(value: float) -> float:
    return value / 1000.0 if value > 1.0 else value
