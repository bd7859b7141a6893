"""Shared pieces of the calibration readers and writers: options, units, file loading and
a :class:`Source` that pulls validated values out of a document, naming the file and the
field in every error."""

from __future__ import annotations

import json
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, validate_rotation

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}  # metres per unit
CAMERA_TYPES = ("hd", "vga", "kinect-color", "all")
CONVENTION = (
    "world->camera x = R X + t; camera centre C = -R^T t; pixels from the top-left corner; "
    "OpenCV distortion (k1, k2, p1, p2, k3); translations in `units`"
)
SAFE_NAME = re.compile(r"[A-Za-z0-9_\-]+")


@dataclass(frozen=True)
class CalibOptions:
    """Options that some formats need; the others ignore them.

    Attributes:
        units: length unit of translations in the file ("m", "cm", "mm"); None for the
            format's own unit.
        camera_type: Panoptic camera type to keep: "hd", "vga", "kinect-color" or "all".
        subject: Human3.6M subject whose extrinsics to read, e.g. "S1".
        binning_factor: Qualisys pixel binning factor (1 unless filming binned video).
    """

    units: str | None = None
    camera_type: str = "hd"
    subject: str = "S1"
    binning_factor: int = 1


Reader = Callable[[Path, CalibOptions], Rig]
Writer = Callable[[Rig, Path, CalibOptions], dict[Path, str]]


def read_text(path: Path) -> str:
    if not path.exists():
        raise InputError(path, None, "an existing file", "no such file")
    if path.is_dir():
        raise InputError(path, None, "a file", "a folder")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise InputError(path, None, "UTF-8 text", f"an undecodable byte at {e.start}") from None
    except OSError as e:
        raise InputError(path, None, "a readable file", e.strerror or type(e).__name__) from None
    if not text.strip():
        raise InputError(path, None, "a non-empty calibration file", "an empty file")
    return text


class _RepeatedKey(Exception):
    def __init__(self, key: str) -> None:
        self.key = key


def _unique_object(pairs: list[tuple[str, object]]) -> dict:
    """A JSON object that refuses a repeated key (json.load would keep the last entry)."""
    seen: dict = {}
    for key, value in pairs:
        if key in seen:
            raise _RepeatedKey(key)
        seen[key] = value
    return seen


def load_json(path: Path) -> object:
    """The JSON document in ``path``; a key repeated in one object is an error."""
    try:
        return json.loads(read_text(path), object_pairs_hook=_unique_object)
    except json.JSONDecodeError as e:
        raise InputError(
            path, None, "valid JSON", f"{e.msg} at line {e.lineno} column {e.colno}"
        ) from None
    except _RepeatedKey as e:
        raise InputError(
            path, e.key, "each key once per JSON object (one entry per camera)", "it repeated"
        ) from None


def load_toml(path: Path) -> dict:
    try:
        return tomllib.loads(read_text(path))
    except tomllib.TOMLDecodeError as e:
        raise InputError(path, None, "valid TOML", str(e)) from None


def join_field(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def unit_scale(path: Path, units: object, field: str = "units") -> float:
    """Metres per file unit."""
    if units not in UNITS:
        raise InputError(path, field, f"a length unit, one of {sorted(UNITS)}", units)
    return UNITS[units]


@dataclass(frozen=True)
class Source:
    """A file being read: pulls typed values out of it; every error names the file."""

    path: Path

    def value(self, table: object, key: str, where: str, expected: str) -> object:
        """``table[key]``; ``where`` is the table's field name, ``expected`` the value's."""
        if not isinstance(table, dict):
            raise InputError(self.path, where or None, "a table of fields", type(table).__name__)
        if key not in table:
            raise InputError(self.path, join_field(where, key), expected, "nothing (missing key)")
        return table[key]

    def table(self, table: object, key: str, where: str) -> dict:
        value = self.value(table, key, where, "a table of fields")
        if not isinstance(value, dict):
            raise InputError(
                self.path, join_field(where, key), "a table of fields", type(value).__name__
            )
        return value

    def numbers(
        self, value: object, shape: tuple[int, ...], field: str, expected: str
    ) -> np.ndarray:
        """Finite floats of ``shape``; a vector may also come as one row or one column."""
        if _has_bool(value):  # true/false would pass as 1/0
            raise InputError(
                self.path, field, f"{expected} (numbers, not true/false)", brief(value)
            )
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(self.path, field, expected, brief(value)) from None
        if a.shape != shape:
            vector = len(shape) == 1 and a.ndim == 2 and 1 in a.shape and a.size == shape[0]
            if not vector:
                raise InputError(self.path, field, expected, f"shape {a.shape}")
            a = a.reshape(shape)
        if not np.all(np.isfinite(a)):
            raise InputError(self.path, field, f"{expected} (finite numbers)", a.tolist())
        return a

    def array(
        self, table: object, key: str, where: str, shape: tuple[int, ...], expected: str
    ) -> np.ndarray:
        field = join_field(where, key)
        return self.numbers(self.value(table, key, where, expected), shape, field, expected)

    def number(self, table: object, key: str, where: str) -> float:
        return float(self.array(table, key, where, (), "a number"))

    def intrinsics(self, K: np.ndarray, field: str) -> np.ndarray:
        """Check an upper-triangular K with positive focal lengths and last row (0, 0, 1)."""
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise InputError(
                self.path, field, "positive focal lengths K[0,0], K[1,1]", (K[0, 0], K[1, 1])
            )
        if not np.allclose([K[1, 0], K[2, 0], K[2, 1], K[2, 2]], [0, 0, 0, 1], atol=1e-9):
            raise InputError(
                self.path,
                field,
                "an intrinsic matrix with rows [fx s cx], [0 fy cy], [0 0 1]",
                K.tolist(),
            )
        return K

    def rotation(self, R: np.ndarray, field: str) -> np.ndarray:
        try:
            return validate_rotation(R, field)
        except ValueError:
            err = float(np.abs(R @ R.T - np.eye(3)).max())
            raise InputError(
                self.path,
                field,
                "a rotation matrix (R R^T = I, det R = +1)",
                f"|R R^T - I| = {err:.2e}, det R = {np.linalg.det(R):.4f}",
            ) from None

    def distortion(self, value: object, field: str) -> np.ndarray:
        expected = "4 or 5 distortion coefficients (k1 k2 p1 p2 [k3])"
        try:
            d = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(self.path, field, expected, brief(value)) from None
        if d.size not in (4, 5) or sum(n > 1 for n in d.shape) > 1:
            raise InputError(self.path, field, expected, f"shape {d.shape}")
        return self.numbers(np.pad(d.ravel(), (0, 5 - d.size)), (5,), field, expected)

    def size(self, value: object, field: str) -> tuple[int, int]:
        expected = "an image size [width, height] in whole pixels"
        wh = self.numbers(value, (2,), field, expected)
        if np.any(wh <= 0) or np.any(np.abs(wh - np.round(wh)) > 1e-6):
            raise InputError(self.path, field, expected, wh.tolist())
        return int(round(wh[0])), int(round(wh[1]))

    def rig(self, cameras: list[Camera], where: str = "cameras") -> Rig:
        if not cameras:
            raise InputError(self.path, where, "at least one camera", "none")
        names = [c.name for c in cameras]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise InputError(self.path, where, "unique camera names", f"repeated {dupes}")
        return Rig(tuple(cameras))


def _has_bool(value: object) -> bool:
    if isinstance(value, bool | np.bool_):
        return True
    if isinstance(value, np.ndarray):
        return value.dtype == bool or (value.dtype == object and _has_bool(value.tolist()))
    return isinstance(value, list | tuple) and any(_has_bool(v) for v in value)


def brief(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def make_camera(
    name: str,
    K: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    dist: np.ndarray | None,
    size: tuple[int, int] | None,
) -> Camera:
    return Camera(K=K, R=R, t=t, dist=np.zeros(5) if dist is None else dist, size=size, name=name)
