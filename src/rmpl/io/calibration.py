"""Camera calibration files: read many formats into a :class:`~rmpl.geometry.camera.Rig`.

Every reader returns cameras in rmpl's convention (see :mod:`rmpl.geometry.camera`):
world -> camera ``x = R X + t``, centre ``C = -R^T t``, pixels from the top-left corner,
OpenCV distortion ``(k1, k2, p1, p2, k3)``, lengths in metres.

Formats (``FORMATS[name] = (reader, writer or None)``):

============  =====  ==================================================================
name          write  file and units
============  =====  ==================================================================
rmpl-toml     yes    our own TOML, described below; units from ``[metadata] units``
rmpl-json     yes    the same document as JSON
anipose       yes    anipose / Pose2Sim TOML: one table per camera with ``name``,
                     ``size``, ``matrix``, ``distortions`` (4 or 5), ``rotation``
                     (Rodrigues), ``translation``, ``fisheye``; plus ``[metadata]``.
                     Pose2Sim writes metres; anipose uses the unit of the calibration
                     board (often mm), so pass ``units`` when it is not metres.
panoptic      yes    CMU Panoptic ``calibration_<seq>.json``; ``t`` in centimetres;
                     ``camera_type`` picks ``hd`` (default), ``vga``, ``kinect-color``
                     or ``all``. Cameras are named as in the file (``"00_03"``).
shelf4d       yes    4D-association Shelf/Campus ``calibration.json``: per camera ``K``
                     (9 numbers), ``RT`` (12 numbers, row-major ``[R | t]``), ``imgSize``;
                     metres; no distortion (writing a distorted camera is refused).
voxelpose     yes    VoxelPose ``calibration_shelf.json`` / ``calibration_campus.json``:
                     per camera ``R``, ``T`` (the camera CENTRE in world millimetres),
                     ``fx fy cx cy``, ``k`` (k1 k2 k3), ``p`` (p1 p2). No image size
                     and no skew.
easymocap     yes    EasyMocap OpenCV FileStorage YAML: ``intri.yml`` (``names``,
                     ``K_<name>``, ``dist_<name>``, optional ``H_<name>``/``W_<name>``)
                     and ``extri.yml`` (``R_<name>`` Rodrigues, ``Rot_<name>``,
                     ``T_<name>``) in one folder; metres. Pass the folder or either file.
h36m          no     Human3.6M ``camera-parameters.json`` (``intrinsics`` per camera id,
                     ``extrinsics`` per subject; ``t`` in millimetres); ``subject``
                     picks the subject (default ``S1``). Image sizes are the dataset's.
h36m-pkl      no     the H36M ``cameras.pkl`` used by mmpose: a dict keyed by
                     ``(subject, camera id)`` with ``R`` (camera -> world, i.e. the
                     transpose of rmpl's R), ``T`` (camera centre, metres), ``f``, ``c``,
                     ``k``, ``p``, ``w``, ``h``. Loaded with an unpickler that accepts
                     only plain containers and numpy arrays.
qualisys      no     Qualisys ``.qca.txt`` XML as read by Pose2Sim: video cameras only,
                     sorted by serial; focal length and principal point in 1/64 pixel,
                     divided by ``binning_factor`` and rescaled to the video resolution,
                     principal point shifted by the video window offset; distortion
                     (k1 k2 p1 p2) divided by 64 and the binning factor as Pose2Sim does;
                     ``transform`` holds the camera pose (position in mm, rotation with
                     the camera axes as columns) whose y and z axes are flipped to reach
                     OpenCV's camera frame.
============  =====  ==================================================================

``units`` (``"m"``, ``"cm"`` or ``"mm"``) is the length unit of the translations in the
file. ``None`` means the format's own unit above; a value overrides it.

The rmpl format (TOML shown; the JSON form holds the same keys)::

    [metadata]
    format = "rmpl"
    version = 1
    units = "m"
    convention = "world->camera x = R X + t; ..."

    [[cameras]]
    name = "cam0"
    K = [[1000.0, 0.0, 640.0], [0.0, 1000.0, 360.0], [0.0, 0.0, 1.0]]   # pixels
    R = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]             # world->camera
    t = [0.0, 0.0, 3.0]                                                 # in `units`
    dist = [0.0, 0.0, 0.0, 0.0, 0.0]                                    # k1 k2 p1 p2 k3
    size = [1280, 720]                                                  # width, height

``name``, ``K``, ``R`` and ``t`` are required; ``dist`` defaults to zeros and ``size`` to
unknown. Every reader validates what it reads and raises :class:`rmpl.errors.InputError`
naming the file and the field for missing keys, wrong shapes, non-finite numbers, matrices
that are not rotations, empty files and unknown formats.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import json
import logging
import math
import pickle
import re
import tomllib
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import (
    Camera,
    Rig,
    rodrigues,
    rotation_to_rodrigues,
    validate_rotation,
)
from rmpl.io.atomic import atomic_path

__all__ = [
    "FORMATS",
    "UNITS",
    "CAMERA_TYPES",
    "CalibOptions",
    "detect_format",
    "load_rig",
    "save_rig",
]

log = logging.getLogger(__name__)

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}  # metres per unit
CAMERA_TYPES = ("hd", "vga", "kinect-color", "all")
CONVENTION = (
    "world->camera x = R X + t; camera centre C = -R^T t; pixels from the top-left corner; "
    "OpenCV distortion (k1, k2, p1, p2, k3); translations in `units`"
)
# Image sizes of the four Human3.6M cameras (width, height), pixels.
_H36M_SIZES = {
    "54138969": (1000, 1002),
    "55011271": (1000, 1000),
    "58860488": (1000, 1000),
    "60457274": (1000, 1002),
}
_QUALISYS_VIDEO_MODELS = ("Miqus Video", "Miqus Video UnderWater", "none")
_SAFE_NAME = re.compile(r"[A-Za-z0-9_\-]+")


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


# ---------------------------------------------------------------------------------------
# Public API


def load_rig(
    path: str | Path,
    format: str | None = None,
    *,
    units: str | None = None,
    camera_type: str = "hd",
    subject: str = "S1",
    binning_factor: int = 1,
) -> Rig:
    """Read a calibration file (or an EasyMocap folder) into a rig.

    Args:
        path: the calibration file; for EasyMocap the folder or either YAML file.
        format: a key of :data:`FORMATS`; None detects it from the extension and content.
        units: length unit of the file's translations ("m", "cm", "mm"); None for the
            format's own unit (see the module docstring).
        camera_type: Panoptic only: "hd", "vga", "kinect-color" or "all".
        subject: Human3.6M only: the subject whose extrinsics to read.
        binning_factor: Qualisys only: the pixel binning factor.

    Returns:
        The V cameras, translations in metres.

    Raises:
        InputError: the file is missing, empty, of an unknown format, or holds a bad field.
    """
    path = Path(path)
    name = format or detect_format(path)
    reader = _lookup(path, name)[0]
    options = CalibOptions(units, camera_type, subject, binning_factor)
    rig = reader(path, options)
    log.debug("read %d cameras (%s) from %s as %s", len(rig), ", ".join(rig.names), path, name)
    return rig


def save_rig(
    rig: Rig,
    path: str | Path,
    format: str | None = None,
    *,
    units: str | None = None,
    camera_type: str = "hd",
) -> None:
    """Write a rig; every file appears whole or not at all.

    Args:
        rig: the V cameras, translations in metres.
        path: output file; for EasyMocap a folder (or its ``intri.yml``).
        format: a writable key of :data:`FORMATS`; None picks it from the extension
            (``.toml`` rmpl-toml, ``.json`` rmpl-json, ``.yml``/``.yaml`` or no extension
            easymocap).
        units: length unit to write translations in; None for the format's own unit.
        camera_type: Panoptic only: the ``type`` written for every camera; "all" derives
            it from Panoptic names ("00_*" hd, "50_*" kinect-color, others vga).

    Raises:
        InputError: unknown or read-only format, or a rig the format cannot represent
            (distortion for shelf4d, skew for voxelpose, unsafe names for easymocap).
    """
    path = Path(path)
    name = format or _output_format(path)
    writer = _lookup(path, name)[1]
    if writer is None:
        raise InputError(path, "format", f"a writable format, one of {_writable()}", name)
    files = writer(rig, path, CalibOptions(units=units, camera_type=camera_type))
    with contextlib.ExitStack() as stack:
        tmps = {dst: stack.enter_context(atomic_path(dst)) for dst in files}
        for dst, text in files.items():
            tmps[dst].write_text(text, encoding="utf-8")
    log.debug("wrote %d cameras to %s as %s", len(rig), path, name)


def detect_format(path: str | Path) -> str:
    """Guess a calibration file's format from its extension and content.

    Args:
        path: a calibration file, or a folder holding EasyMocap ``intri.yml``.

    Returns:
        A key of :data:`FORMATS`.

    Raises:
        InputError: the file is missing or empty, or no known format matches.
    """
    p = Path(path)
    if p.is_dir():
        if (p / "intri.yml").is_file():
            return "easymocap"
        raise InputError(
            p,
            None,
            "a calibration file or a folder with intri.yml/extri.yml",
            "a folder without intri.yml",
        )
    lower = p.name.lower()
    if lower.endswith((".yml", ".yaml")):
        return "easymocap"
    if lower.endswith((".pkl", ".pickle")):
        return "h36m-pkl"
    if lower.endswith((".qca.txt", ".qca", ".xml")):
        return "qualisys"
    if lower.endswith(".toml"):
        return _toml_kind(_load_toml(p))
    if lower.endswith(".json"):
        return _json_kind(p, _load_json(p))
    if lower.endswith(".txt") and _read_text(p).lstrip().startswith("<"):
        return "qualisys"
    raise InputError(
        p,
        "format",
        "a known extension (.toml .json .yml .pkl .qca.txt) or an explicit format, "
        f"one of {sorted(FORMATS)}",
        p.suffix or "no extension",
    )


def _lookup(path: Path, name: str) -> tuple[Reader, Writer | None]:
    if name not in FORMATS:
        raise InputError(path, "format", f"one of {sorted(FORMATS)}", name)
    return FORMATS[name]


def _writable() -> list[str]:
    return sorted(k for k, (_, w) in FORMATS.items() if w is not None)


def _output_format(path: Path) -> str:
    lower = path.name.lower()
    if lower.endswith(".toml"):
        return "rmpl-toml"
    if lower.endswith(".json"):
        return "rmpl-json"
    if lower.endswith((".yml", ".yaml")) or not path.suffix:
        return "easymocap"
    raise InputError(
        path,
        "format",
        f"an extension .toml/.json/.yml or a format, one of {_writable()}",
        path.suffix,
    )


# ---------------------------------------------------------------------------------------
# Reading and validating


def _read_text(path: Path) -> str:
    if not path.exists():
        raise InputError(path, None, "an existing file", "no such file")
    if path.is_dir():
        raise InputError(path, None, "a file", "a folder")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise InputError(path, None, "UTF-8 text", f"an undecodable byte at {e.start}") from None
    if not text.strip():
        raise InputError(path, None, "a non-empty calibration file", "an empty file")
    return text


def _load_json(path: Path) -> object:
    try:
        return json.loads(_read_text(path))
    except json.JSONDecodeError as e:
        raise InputError(
            path, None, "valid JSON", f"{e.msg} at line {e.lineno} column {e.colno}"
        ) from None


def _load_toml(path: Path) -> dict:
    try:
        return tomllib.loads(_read_text(path))
    except tomllib.TOMLDecodeError as e:
        raise InputError(path, None, "valid TOML", str(e)) from None


def _toml_kind(doc: dict) -> str:
    meta = doc.get("metadata")
    if (isinstance(meta, dict) and meta.get("format") == "rmpl") or isinstance(
        doc.get("cameras"), list
    ):
        return "rmpl-toml"
    return "anipose"


def _json_kind(path: Path, doc: object) -> str:
    if isinstance(doc, dict):
        meta = doc.get("metadata")
        if isinstance(meta, dict) and meta.get("format") == "rmpl":
            return "rmpl-json"
        cams = doc.get("cameras")
        if isinstance(cams, list):
            panoptic = any(isinstance(c, dict) and "distCoef" in c for c in cams)
            return "panoptic" if panoptic else "rmpl-json"
        if "intrinsics" in doc and "extrinsics" in doc:
            return "h36m"
        entries = list(doc.values())
        if entries and all(isinstance(v, dict) for v in entries):
            if "RT" in entries[0]:
                return "shelf4d"
            if "fx" in entries[0] or "T" in entries[0]:
                return "voxelpose"
    keys = list(doc)[:6] if isinstance(doc, dict) else type(doc).__name__
    raise InputError(
        path,
        "format",
        "a known JSON calibration layout (rmpl-json, panoptic, shelf4d, voxelpose, h36m) "
        "or an explicit format",
        f"top-level {keys}",
    )


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _scale(path: Path, units: object, field: str = "units") -> float:
    """Metres per file unit."""
    if units not in UNITS:
        raise InputError(path, field, f"a length unit, one of {sorted(UNITS)}", units)
    return UNITS[units]


@dataclass(frozen=True)
class _Src:
    """A file being read: pulls typed values out of it; every error names the file."""

    path: Path

    def value(self, table: object, key: str, where: str, expected: str) -> object:
        """``table[key]``; ``where`` is the table's field name, ``expected`` the value's."""
        if not isinstance(table, dict):
            raise InputError(self.path, where or None, "a table of fields", type(table).__name__)
        if key not in table:
            raise InputError(self.path, _join(where, key), expected, "nothing (missing key)")
        return table[key]

    def table(self, table: object, key: str, where: str) -> dict:
        value = self.value(table, key, where, "a table of fields")
        if not isinstance(value, dict):
            raise InputError(
                self.path, _join(where, key), "a table of fields", type(value).__name__
            )
        return value

    def numbers(
        self, value: object, shape: tuple[int, ...], field: str, expected: str
    ) -> np.ndarray:
        """Finite floats of ``shape``; a vector may also come as one row or one column."""
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(self.path, field, expected, _brief(value)) from None
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
        field = _join(where, key)
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
            raise InputError(self.path, field, expected, _brief(value)) from None
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


def _brief(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _camera(
    name: str,
    K: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    dist: np.ndarray | None,
    size: tuple[int, int] | None,
) -> Camera:
    return Camera(K=K, R=R, t=t, dist=np.zeros(5) if dist is None else dist, size=size, name=name)


# ---------------------------------------------------------------------------------------
# rmpl (TOML and JSON)


def _read_rmpl_doc(src: _Src, doc: object, options: CalibOptions) -> Rig:
    meta = src.table(doc, "metadata", "") if isinstance(doc, dict) and "metadata" in doc else {}
    units = options.units or meta.get("units", "m")
    scale = _scale(src.path, units, "metadata.units")
    cams = src.value(doc, "cameras", "", "a list of cameras")
    if not isinstance(cams, list):
        raise InputError(src.path, "cameras", "a list of cameras", type(cams).__name__)
    return src.rig([_read_rmpl_camera(src, c, f"cameras[{i}]", scale) for i, c in enumerate(cams)])


def _read_rmpl_camera(src: _Src, cam: object, where: str, scale: float) -> Camera:
    name = src.value(cam, "name", where, "a camera name")
    K = src.intrinsics(src.array(cam, "K", where, (3, 3), "a 3x3 matrix"), f"{where}.K")
    R = src.rotation(src.array(cam, "R", where, (3, 3), "a 3x3 matrix"), f"{where}.R")
    t = src.array(cam, "t", where, (3,), "3 numbers") * scale
    dist = src.distortion(cam["dist"], f"{where}.dist") if "dist" in cam else None
    size = src.size(cam["size"], f"{where}.size") if "size" in cam else None
    return _camera(str(name), K, R, t, dist, size)


def read_rmpl_toml(path: Path, options: CalibOptions) -> Rig:
    """Read rmpl's TOML calibration (see the module docstring)."""
    return _read_rmpl_doc(_Src(path), _load_toml(path), options)


def read_rmpl_json(path: Path, options: CalibOptions) -> Rig:
    """Read rmpl's JSON calibration (see the module docstring)."""
    return _read_rmpl_doc(_Src(path), _load_json(path), options)


def _rmpl_doc(rig: Rig, path: Path, options: CalibOptions) -> dict:
    units = options.units or "m"
    scale = _scale(path, units)
    cams = []
    for c in rig:
        cam = {
            "name": c.name,
            "K": c.K.tolist(),
            "R": c.R.tolist(),
            "t": (c.t / scale).tolist(),
            "dist": c.dist.tolist(),
        }
        if c.size is not None:
            cam["size"] = list(c.size)
        cams.append(cam)
    meta = {"format": "rmpl", "version": 1, "units": units, "convention": CONVENTION}
    return {"metadata": meta, "cameras": cams}


def write_rmpl_toml(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """rmpl's TOML calibration text for ``path``."""
    return {path: "# rmpl camera calibration\n" + _toml_dumps(_rmpl_doc(rig, path, options))}


def write_rmpl_json(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """rmpl's JSON calibration text for ``path``."""
    return {path: _json_dumps(_rmpl_doc(rig, path, options))}


# ---------------------------------------------------------------------------------------
# anipose / Pose2Sim TOML


def read_anipose(path: Path, options: CalibOptions) -> Rig:
    """Read an anipose / Pose2Sim TOML calibration (translations in ``units``, default m)."""
    src, doc = _Src(path), _load_toml(path)
    meta = doc.get("metadata", {})
    units = options.units or (meta.get("units", "m") if isinstance(meta, dict) else "m")
    scale = _scale(path, units, "metadata.units")
    cams = [_read_anipose_camera(src, doc, key, scale) for key in doc if key != "metadata"]
    return src.rig(cams, "camera tables")


def _read_anipose_camera(src: _Src, doc: dict, key: str, scale: float) -> Camera:
    cam = src.table(doc, key, "")
    if cam.get("fisheye", False) is not False:
        raise InputError(
            src.path, f"{key}.fisheye", "false (fisheye lenses are not supported)", cam["fisheye"]
        )
    K = src.intrinsics(src.array(cam, "matrix", key, (3, 3), "a 3x3 matrix"), f"{key}.matrix")
    dist = src.distortion(
        src.value(cam, "distortions", key, "4 or 5 numbers"), f"{key}.distortions"
    )
    rvec = src.array(cam, "rotation", key, (3,), "a Rodrigues vector (3 numbers)")
    t = src.array(cam, "translation", key, (3,), "3 numbers") * scale
    size = src.size(cam["size"], f"{key}.size") if "size" in cam else None
    return _camera(str(cam.get("name", key)), K, rodrigues(rvec), t, dist, size)


def write_anipose(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """anipose / Pose2Sim TOML text; one table per camera, keyed by its name."""
    units = options.units or "m"
    scale = _scale(path, units)
    doc: dict = {}
    for i, c in enumerate(rig):
        key = c.name if c.name != "metadata" else f"cam_{i}"
        cam = {"name": c.name}
        if c.size is not None:
            cam["size"] = list(c.size)
        cam |= {
            "matrix": c.K.tolist(),
            "distortions": c.dist.tolist(),
            "rotation": rotation_to_rodrigues(c.R).tolist(),
            "translation": (c.t / scale).tolist(),
            "fisheye": False,
        }
        doc[key] = cam
    doc["metadata"] = {"adjusted": False, "error": 0.0, "units": units}
    return {path: _toml_dumps(doc)}


# ---------------------------------------------------------------------------------------
# CMU Panoptic


def read_panoptic(path: Path, options: CalibOptions) -> Rig:
    """Read a CMU Panoptic ``calibration_<seq>.json`` (t in cm), keeping ``camera_type``."""
    src, doc = _Src(path), _load_json(path)
    if options.camera_type not in CAMERA_TYPES:
        raise InputError(path, "camera_type", f"one of {list(CAMERA_TYPES)}", options.camera_type)
    scale = _scale(path, options.units or "cm")
    cams = src.value(doc, "cameras", "", "a list of cameras")
    if not isinstance(cams, list):
        raise InputError(path, "cameras", "a list of cameras", type(cams).__name__)
    types = [
        str(src.value(c, "type", f"cameras[{i}]", "a camera type")) for i, c in enumerate(cams)
    ]
    keep = [i for i, ty in enumerate(types) if options.camera_type in ("all", ty)]
    if not keep:
        raise InputError(
            path,
            "cameras[].type",
            f"cameras of type {options.camera_type!r}",
            f"types {sorted(set(types))}",
        )
    return src.rig([_read_panoptic_camera(src, cams[i], f"cameras[{i}]", scale) for i in keep])


def _read_panoptic_camera(src: _Src, cam: dict, where: str, scale: float) -> Camera:
    name = src.value(cam, "name", where, "a camera name")
    K = src.intrinsics(src.array(cam, "K", where, (3, 3), "a 3x3 matrix"), f"{where}.K")
    dist = src.distortion(src.value(cam, "distCoef", where, "5 numbers"), f"{where}.distCoef")
    R = src.rotation(src.array(cam, "R", where, (3, 3), "a 3x3 matrix"), f"{where}.R")
    t = src.array(cam, "t", where, (3,), "3 numbers") * scale
    size = src.size(cam["resolution"], f"{where}.resolution") if "resolution" in cam else None
    return _camera(str(name), K, R, t, dist, size)


def _panoptic_type(name: str, camera_type: str) -> tuple[str, dict]:
    """Type and panel/node of a camera; names "PP_NN" give the panel (0 HD, 50 Kinect)."""
    m = re.fullmatch(r"(\d+)_(\d+)", name)
    panel = {"panel": int(m[1]), "node": int(m[2])} if m else {}
    if camera_type != "all":
        return camera_type, panel
    return {0: "hd", 50: "kinect-color"}.get(panel.get("panel", 0), "vga"), panel


def write_panoptic(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """CMU Panoptic calibration JSON (t in cm unless ``units``), type ``camera_type``."""
    if options.camera_type not in CAMERA_TYPES:
        raise InputError(path, "camera_type", f"one of {list(CAMERA_TYPES)}", options.camera_type)
    scale = _scale(path, options.units or "cm")
    cams = []
    for c in rig:
        kind, panel = _panoptic_type(c.name, options.camera_type)
        cam = {"name": c.name, "type": kind}
        if c.size is not None:
            cam["resolution"] = list(c.size)
        cam |= panel | {
            "K": c.K.tolist(),
            "distCoef": c.dist.tolist(),
            "R": c.R.tolist(),
            "t": (c.t / scale)[:, None].tolist(),
        }
        cams.append(cam)
    return {path: _json_dumps({"calibDataSource": "rmpl", "cameras": cams})}


# ---------------------------------------------------------------------------------------
# Shelf / Campus: 4D-association and VoxelPose


def read_shelf4d(path: Path, options: CalibOptions) -> Rig:
    """Read a 4D-association ``calibration.json`` (K 9, RT 12 row-major, metres)."""
    src, doc = _Src(path), _load_json(path)
    if not isinstance(doc, dict):
        raise InputError(path, None, "an object of cameras", type(doc).__name__)
    scale = _scale(path, options.units or "m")
    cams = []
    for key, cam in doc.items():
        K = src.intrinsics(
            src.array(cam, "K", key, (9,), "9 numbers (row-major 3x3)").reshape(3, 3), f"{key}.K"
        )
        RT = src.array(cam, "RT", key, (12,), "12 numbers (row-major 3x4 [R | t])").reshape(3, 4)
        R = src.rotation(RT[:, :3], f"{key}.RT")
        size = src.size(cam["imgSize"], f"{key}.imgSize") if "imgSize" in cam else None
        cams.append(_camera(str(key), K, R, RT[:, 3] * scale, None, size))
    return src.rig(cams, "cameras")


def write_shelf4d(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """4D-association calibration JSON; refuses cameras with lens distortion."""
    scale = _scale(path, options.units or "m")
    doc = {}
    for c in rig:
        if np.any(c.dist != 0):
            raise InputError(
                path, f"{c.name}.dist", "no lens distortion (shelf4d stores none)", c.dist.tolist()
            )
        RT = np.concatenate([c.R, c.t[:, None] / scale], axis=1)
        cam = {"K": c.K.ravel().tolist(), "RT": RT.ravel().tolist()}
        if c.size is not None:
            cam["imgSize"] = list(c.size)
        doc[c.name] = cam
    return {path: _json_dumps(doc)}


def read_voxelpose(path: Path, options: CalibOptions) -> Rig:
    """Read a VoxelPose Shelf/Campus calibration (T = camera centre, millimetres)."""
    src, doc = _Src(path), _load_json(path)
    if not isinstance(doc, dict):
        raise InputError(path, None, "an object of cameras", type(doc).__name__)
    scale = _scale(path, options.units or "mm")
    cams = []
    for key, cam in doc.items():
        fx, fy, cx, cy = (src.number(cam, k, key) for k in ("fx", "fy", "cx", "cy"))
        K = src.intrinsics(np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]), f"{key}.fx/fy")
        R = src.rotation(src.array(cam, "R", key, (3, 3), "a 3x3 matrix"), f"{key}.R")
        centre = src.array(cam, "T", key, (3,), "3 numbers (camera centre)") * scale
        k = src.array(cam, "k", key, (3,), "3 numbers (k1 k2 k3)")
        p = src.array(cam, "p", key, (2,), "2 numbers (p1 p2)")
        dist = np.array([k[0], k[1], p[0], p[1], k[2]])
        cams.append(_camera(str(key), K, R, -R @ centre, dist, None))
    return src.rig(cams, "cameras")


def write_voxelpose(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """VoxelPose calibration JSON (T = centre in mm); drops image sizes, refuses skew."""
    scale = _scale(path, options.units or "mm")
    doc = {}
    for c in rig:
        if c.K[0, 1] != 0:
            raise InputError(
                path, f"{c.name}.K", "zero skew (voxelpose stores fx fy cx cy)", c.K[0, 1]
            )
        k1, k2, p1, p2, k3 = c.dist.tolist()
        doc[c.name] = {
            "k": [[k1], [k2], [k3]],
            "p": [[p1], [p2]],
            "R": c.R.tolist(),
            "T": (c.center / scale)[:, None].tolist(),
            "fx": float(c.K[0, 0]),
            "fy": float(c.K[1, 1]),
            "cx": float(c.K[0, 2]),
            "cy": float(c.K[1, 2]),
        }
    if any(c.size is not None for c in rig):
        log.warning("%s: the voxelpose format stores no image sizes; they are dropped", path)
    return {path: _json_dumps(doc)}


# ---------------------------------------------------------------------------------------
# EasyMocap (OpenCV FileStorage YAML)


def _easymocap_paths(path: Path) -> tuple[Path, Path]:
    """(intri.yml, extri.yml) for a folder, for extri.yml, or for an intrinsics file."""
    if path.is_dir() or not path.suffix:
        return path / "intri.yml", path / "extri.yml"
    if path.name == "extri.yml":
        return path.parent / "intri.yml", path
    return path, path.parent / "extri.yml"


def read_easymocap(path: Path, options: CalibOptions) -> Rig:
    """Read EasyMocap ``intri.yml`` + ``extri.yml`` (a folder or either file; metres)."""
    intri_path, extri_path = _easymocap_paths(path)
    intri, extri = _Src(intri_path), _Src(extri_path)
    idoc = _parse_opencv_yaml(intri_path, _read_text(intri_path))
    edoc = _parse_opencv_yaml(extri_path, _read_text(extri_path))
    scale = _scale(path, options.units or "m")
    names = intri.value(idoc, "names", "", "a list of camera names")
    if not isinstance(names, list):
        raise InputError(intri_path, "names", "a list of camera names", _brief(names))
    cams = []
    for name in names:
        K = intri.intrinsics(
            intri.array(idoc, f"K_{name}", "", (3, 3), "a 3x3 opencv-matrix"), f"K_{name}"
        )
        dist = intri.distortion(
            intri.value(idoc, f"dist_{name}", "", "a 1x5 opencv-matrix"), f"dist_{name}"
        )
        size = None
        if f"W_{name}" in idoc and f"H_{name}" in idoc:
            size = intri.size([idoc[f"W_{name}"], idoc[f"H_{name}"]], f"W_{name}/H_{name}")
        R = _easymocap_rotation(extri, edoc, name)
        t = extri.array(edoc, f"T_{name}", "", (3,), "a 3x1 opencv-matrix") * scale
        cams.append(_camera(name, K, R, t, dist, size))
    return intri.rig(cams, "names")


def _easymocap_rotation(src: _Src, doc: dict, name: str) -> np.ndarray:
    rot_key, rvec_key = f"Rot_{name}", f"R_{name}"
    if rot_key not in doc:
        return rodrigues(src.array(doc, rvec_key, "", (3,), "a 3x1 Rodrigues opencv-matrix"))
    R = src.rotation(src.array(doc, rot_key, "", (3, 3), "a 3x3 opencv-matrix"), rot_key)
    if rvec_key in doc:
        rvec = src.array(doc, rvec_key, "", (3,), "a 3x1 Rodrigues opencv-matrix")
        if np.abs(rodrigues(rvec) - R).max() > 1e-4:
            raise InputError(
                src.path, rvec_key, f"a Rodrigues vector agreeing with {rot_key}", rvec.tolist()
            )
    return R


def write_easymocap(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """EasyMocap ``intri.yml`` and ``extri.yml`` in the folder ``path`` (or beside it)."""
    intri_path, extri_path = _easymocap_paths(path)
    scale = _scale(path, options.units or "m")
    for c in rig:
        if not _SAFE_NAME.fullmatch(c.name):
            raise InputError(
                path,
                "name",
                "camera names of letters, digits, '_' or '-' (they become YAML keys)",
                c.name,
            )
    names = "names:\n" + "".join(f'   - "{c.name}"\n' for c in rig)
    intri, extri = [_YAML_HEADER, names], [_YAML_HEADER, names]
    for c in rig:
        intri += [_yaml_matrix(f"K_{c.name}", c.K), _yaml_matrix(f"dist_{c.name}", c.dist[None])]
        if c.size is not None:
            intri += [f"W_{c.name}: {c.size[0]}\n", f"H_{c.name}: {c.size[1]}\n"]
        extri += [
            _yaml_matrix(f"R_{c.name}", rotation_to_rodrigues(c.R)[:, None]),
            _yaml_matrix(f"Rot_{c.name}", c.R),
            _yaml_matrix(f"T_{c.name}", c.t[:, None] / scale),
        ]
    return {intri_path: "".join(intri), extri_path: "".join(extri)}


_YAML_HEADER = "%YAML:1.0\n---\n"


def _yaml_matrix(key: str, a: np.ndarray) -> str:
    data = ", ".join(repr(float(x)) for x in a.ravel())
    return (
        f"{key}: !!opencv-matrix\n   rows: {a.shape[0]}\n   cols: {a.shape[1]}\n"
        f"   dt: d\n   data: [ {data} ]\n"
    )


def _parse_opencv_yaml(path: Path, text: str) -> dict[str, object]:
    """Parse the subset of OpenCV FileStorage YAML that calibration files use.

    Top-level ``key: value`` entries only: scalars (returned as strings), sequences of
    scalars (block ``- x`` or flow ``[x, y]``; lists of strings) and ``!!opencv-matrix``
    (float arrays of shape (rows, cols)).
    """
    lines = text.splitlines()
    if not lines[0].startswith("%YAML"):
        raise InputError(
            path, None, "an OpenCV FileStorage YAML starting with '%YAML:1.0'", _brief(lines[0])
        )
    entries: list[tuple[str, str, list[str]]] = []
    for number, raw in enumerate(lines[1:], start=2):
        line = _strip_yaml_comment(raw).rstrip()
        if not line.strip() or line.strip() == "---":
            continue
        if line[0] not in " \t-":
            key, sep, rest = line.partition(":")
            if not sep:
                raise InputError(path, f"line {number}", "'key: value'", _brief(raw))
            entries.append((key.strip(), rest.strip(), []))
        elif entries:
            entries[-1][2].append(line.strip())
        else:
            raise InputError(path, f"line {number}", "a top-level 'key: value'", _brief(raw))
    return {key: _yaml_value(path, key, rest, block) for key, rest, block in entries}


def _yaml_value(path: Path, key: str, rest: str, block: list[str]) -> object:
    if rest.startswith("!!opencv-matrix"):
        return _yaml_opencv_matrix(path, key, "\n".join(block))
    if rest.startswith("["):
        flow = " ".join([rest, *block])
        if not flow.endswith("]"):
            raise InputError(path, key, "a flow sequence closed by ']'", _brief(flow))
        return [_unquote(x) for x in _split_flow(flow[1:-1])]
    if not rest and block and all(b.startswith("-") for b in block):
        return [_unquote(b[1:].strip()) for b in block]
    if block:
        raise InputError(
            path, key, "a scalar, a sequence or an !!opencv-matrix", _brief([rest, *block])
        )
    return _unquote(rest)


def _yaml_opencv_matrix(path: Path, key: str, body: str) -> np.ndarray:
    expected = "an !!opencv-matrix with rows, cols, dt and data"
    rows = re.search(r"^rows:\s*(\d+)\s*$", body, re.M)
    cols = re.search(r"^cols:\s*(\d+)\s*$", body, re.M)
    data = re.search(r"^data:\s*\[(.*)\]\s*$", body, re.M | re.S)
    if not (rows and cols and data):
        raise InputError(path, key, expected, _brief(body))
    tokens = [x for x in _split_flow(data[1]) if x]
    shape = (int(rows[1]), int(cols[1]))
    if len(tokens) != shape[0] * shape[1]:
        raise InputError(
            path, key, f"{shape[0] * shape[1]} data values for {shape}", f"{len(tokens)} values"
        )
    return np.array([_yaml_float(path, key, x) for x in tokens]).reshape(shape)


def _yaml_float(path: Path, key: str, token: str) -> float:
    special = {".nan": math.nan, ".inf": math.inf, "+.inf": math.inf, "-.inf": -math.inf}
    low = token.strip().lower()
    if low in special:
        return special[low]
    try:
        return float(low)
    except ValueError:
        raise InputError(path, key, "numbers in data", _brief(token)) from None


def _strip_yaml_comment(line: str) -> str:
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i]
    return line


def _split_flow(text: str) -> list[str]:
    items, current, quote = [], [], None
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == ",":
            items.append("".join(current).strip())
            current = []
            continue
        current.append(ch)
    last = "".join(current).strip()
    return items + [last] if last else items


def _unquote(token: str) -> str:
    token = token.strip()
    if len(token) >= 2 and token[0] == token[-1] == '"':
        return re.sub(r"\\(.)", r"\1", token[1:-1])
    if len(token) >= 2 and token[0] == token[-1] == "'":
        return token[1:-1].replace("''", "'")
    return token


# ---------------------------------------------------------------------------------------
# Human3.6M (read only)


def read_h36m(path: Path, options: CalibOptions) -> Rig:
    """Read H36M ``camera-parameters.json`` for ``options.subject`` (t in mm)."""
    src, doc = _Src(path), _load_json(path)
    scale = _scale(path, options.units or "mm")
    intrinsics = src.table(doc, "intrinsics", "")
    subjects = src.table(doc, "extrinsics", "")
    if options.subject not in subjects:
        raise InputError(
            path, f"extrinsics.{options.subject}", f"a subject, one of {list(subjects)}", "missing"
        )
    extrinsics = src.table(subjects, options.subject, "extrinsics")
    cams = []
    for cam_id in intrinsics:
        iwhere, ewhere = f"intrinsics.{cam_id}", f"extrinsics.{options.subject}.{cam_id}"
        intr, extr = (
            src.table(intrinsics, cam_id, "intrinsics"),
            src.table(extrinsics, cam_id, f"extrinsics.{options.subject}"),
        )
        K = src.intrinsics(
            src.array(intr, "calibration_matrix", iwhere, (3, 3), "a 3x3 matrix"),
            f"{iwhere}.calibration_matrix",
        )
        dist = src.distortion(
            src.value(intr, "distortion", iwhere, "5 numbers"), f"{iwhere}.distortion"
        )
        R = src.rotation(src.array(extr, "R", ewhere, (3, 3), "a 3x3 matrix"), f"{ewhere}.R")
        t = src.array(extr, "t", ewhere, (3,), "3 numbers") * scale
        cams.append(_camera(str(cam_id), K, R, t, dist, _H36M_SIZES.get(str(cam_id))))
    return src.rig(cams, "intrinsics")


_PICKLE_ALLOWED = {
    ("numpy", "ndarray"),
    ("numpy", "dtype"),
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"),
    ("numpy._core.multiarray", "scalar"),
    ("numpy.core.numeric", "_frombuffer"),
    ("numpy._core.numeric", "_frombuffer"),
    ("builtins", "set"),
    ("builtins", "frozenset"),
    ("builtins", "list"),  # default factories of a defaultdict
    ("builtins", "dict"),
    ("collections", "defaultdict"),
}


class _PlainUnpickler(pickle.Unpickler):
    """Unpickles only builtin containers and numpy arrays; refuses any other global."""

    def find_class(self, module: str, name: str):
        if (module, name) not in _PICKLE_ALLOWED:
            raise pickle.UnpicklingError(f"refused global {module}.{name}")
        if module.startswith("numpy.core.") and importlib.util.find_spec("numpy._core"):
            module = "numpy._core." + module.removeprefix("numpy.core.")
        return super().find_class(module, name)


def load_plain_pickle(path: Path) -> object:
    """A pickle of plain containers and numpy arrays; any other global is refused."""
    if not path.is_file():
        raise InputError(path, None, "an existing file", "no such file")
    data = path.read_bytes()
    if not data.strip():
        raise InputError(path, None, "a non-empty pickle file", "an empty file")
    try:
        return _PlainUnpickler(io.BytesIO(data)).load()
    except Exception as e:  # any failure of an untrusted pickle is bad input
        raise InputError(
            path,
            None,
            "a pickle of plain dicts, lists and numpy arrays",
            f"{type(e).__name__}: {e}",
        ) from None


def read_h36m_pkl(path: Path, options: CalibOptions) -> Rig:
    """Read the mmpose-style H36M ``cameras.pkl`` for ``options.subject`` (T = centre, m)."""
    src, doc = _Src(path), load_plain_pickle(path)
    if not isinstance(doc, dict):
        raise InputError(path, None, "a dict keyed by (subject, camera id)", type(doc).__name__)
    keys = [k for k in doc if isinstance(k, tuple) and len(k) == 2 and k[0] == options.subject]
    if not keys:
        subjects = sorted({str(k[0]) for k in doc if isinstance(k, tuple) and k})
        raise InputError(
            path,
            f"({options.subject!r}, camera)",
            f"cameras of a subject, one of {subjects}",
            "missing",
        )
    scale = _scale(path, options.units or "m")
    return src.rig([_read_h36m_pkl_camera(src, doc[k], f"{k}", scale) for k in keys])


def _read_h36m_pkl_camera(src: _Src, cam: object, where: str, scale: float) -> Camera:
    R_c2w = src.array(cam, "R", where, (3, 3), "a 3x3 matrix (camera -> world)")
    R = src.rotation(R_c2w.T, f"{where}.R")
    centre = src.array(cam, "T", where, (3,), "3 numbers (camera centre)") * scale
    f = src.array(cam, "f", where, (2,), "2 numbers (fx fy)")
    c = src.array(cam, "c", where, (2,), "2 numbers (cx cy)")
    K = src.intrinsics(np.array([[f[0], 0, c[0]], [0, f[1], c[1]], [0, 0, 1.0]]), f"{where}.f")
    k = src.array(cam, "k", where, (3,), "3 numbers (k1 k2 k3)")
    p = src.array(cam, "p", where, (2,), "2 numbers (p1 p2)")
    dist = np.array([k[0], k[1], p[0], p[1], k[2]])
    size = None
    if "w" in cam and "h" in cam:
        size = src.size([cam["w"], cam["h"]], f"{where}.w/h")
    name = str(cam["id"]) if "id" in cam else where
    return _camera(name, K, R, -R @ centre, dist, size)


# ---------------------------------------------------------------------------------------
# Qualisys .qca.txt (read only)


def read_qualisys(path: Path, options: CalibOptions) -> Rig:
    """Read a Qualisys ``.qca.txt`` the way Pose2Sim interprets it (positions in mm)."""
    text = _read_text(path)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise InputError(path, None, "valid XML", str(e)) from None
    binning = options.binning_factor
    if not isinstance(binning, int) or binning < 1:
        raise InputError(path, "binning_factor", "a positive integer", binning)
    scale = _scale(path, options.units or "mm")
    elems = [
        c
        for c in root.findall("cameras/camera")
        if c.get("model", "none") in _QUALISYS_VIDEO_MODELS
    ]
    src = _Src(path)
    cams = [_read_qualisys_camera(src, e, i, binning, scale) for i, e in enumerate(elems)]
    cams.sort(key=lambda c: _natural_key(c.name))
    return src.rig(cams, "cameras/camera")


def _natural_key(name: str) -> list:
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", name)]


def _xml_numbers(
    src: _Src, parent: ET.Element, tag: str, where: str, names: tuple[str, ...]
) -> dict[str, float]:
    elem = parent.find(tag)
    if elem is None:
        raise InputError(src.path, f"{where}.{tag}", f"a <{tag}> element", "nothing")
    return {n: float(src.array(elem.attrib, n, f"{where}.{tag}", (), "a number")) for n in names}


def _read_qualisys_camera(
    src: _Src, elem: ET.Element, index: int, binning: int, scale: float
) -> Camera:
    name = elem.get("serial") or f"camera{index}"
    where = f"camera[{name}]"
    fov = _xml_numbers(src, elem, "fov_video", where, ("left", "top", "right", "bottom"))
    intr = _xml_numbers(
        src,
        elem,
        "intrinsic",
        where,
        (
            "focalLengthU",
            "focalLengthV",
            "centerPointU",
            "centerPointV",
            "radialDistortion1",
            "radialDistortion2",
            "tangentalDistortion1",
            "tangentalDistortion2",
        ),
    )
    pose = _xml_numbers(
        src,
        elem,
        "transform",
        where,
        ("x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33"),
    )
    res = _qualisys_resolution(src, elem, where)
    zoom = res / 1080 / binning  # sensor units (1080p, unbinned) -> video pixels
    size = src.size(
        [(fov["right"] - fov["left"] + 1) * zoom, (fov["bottom"] - fov["top"] + 1) * zoom],
        f"{where}.fov_video",
    )
    fu, fv = intr["focalLengthU"] / 64 * zoom, intr["focalLengthV"] / 64 * zoom
    cu = (intr["centerPointU"] / 64 / binning - fov["left"]) * res / 1080
    cv = (intr["centerPointV"] / 64 / binning - fov["top"]) * res / 1080
    K = src.intrinsics(np.array([[fu, 0, cu], [0, fv, cv], [0, 0, 1.0]]), f"{where}.intrinsic")
    coefs = (
        "radialDistortion1",
        "radialDistortion2",
        "tangentalDistortion1",
        "tangentalDistortion2",
    )
    dist = np.array([intr[k] / 64 / binning for k in coefs] + [0.0])  # as Pose2Sim: no k3
    axes = np.array([[pose[f"r{i}{j}"] for j in (1, 2, 3)] for i in (1, 2, 3)])
    M = src.rotation(axes, f"{where}.transform")  # columns: camera axes in the world
    R = np.diag([1.0, -1.0, -1.0]) @ M  # Qualisys camera frame -> OpenCV's (y down, z ahead)
    centre = np.array([pose["x"], pose["y"], pose["z"]]) * scale
    return _camera(name, K, R, -R @ centre, dist, size)


def _qualisys_resolution(src: _Src, elem: ET.Element, where: str) -> int:
    """Video lines: the ``video_resolution`` attribute ("1080p", "720p", ...), else 1080."""
    text = elem.get("video_resolution")
    if text is None:
        return 1080
    m = re.fullmatch(r"\s*(\d+)\s*[pP]?\s*", text)
    if m is None or int(m[1]) == 0:
        raise InputError(src.path, f"{where}.video_resolution", "a resolution like '1080p'", text)
    return int(m[1])


# ---------------------------------------------------------------------------------------
# Small serialisers


def _json_dumps(doc: object) -> str:
    text = json.dumps(doc, indent=2, ensure_ascii=False, allow_nan=False)
    # Keep each innermost list of numbers on one line.
    return re.sub(r"\[([^\[\]{}\"]*)\]", lambda m: "[" + " ".join(m[1].split()) + "]", text) + "\n"


def _toml_dumps(doc: dict) -> str:
    """TOML for a document of scalars, tables of scalars/arrays, and arrays of such tables."""
    tables = {k: v for k, v in doc.items() if isinstance(v, dict) or _is_table_array(v)}
    out = [_toml_fields({k: v for k, v in doc.items() if k not in tables})]
    for key, value in tables.items():
        for table in [value] if isinstance(value, dict) else value:
            brackets = ("[", "]") if isinstance(value, dict) else ("[[", "]]")
            out.append(f"\n{brackets[0]}{_toml_key(key)}{brackets[1]}\n{_toml_fields(table)}")
    return "".join(out).lstrip("\n")


def _is_table_array(value: object) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _toml_fields(table: dict) -> str:
    return "".join(f"{_toml_key(k)} = {_toml_value(v)}\n" for k, v in table.items())


def _toml_key(key: str) -> str:
    return key if _SAFE_NAME.fullmatch(key) else _toml_str(key)


def _toml_str(text: str) -> str:
    escapes = {'"': '\\"', "\\": "\\\\", "\n": "\\n", "\t": "\\t", "\r": "\\r"}
    out = []
    for ch in text:
        if ch in escapes:
            out.append(escapes[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"cannot write a non-finite number {value} to TOML")
        return repr(value)
    if isinstance(value, str):
        return _toml_str(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


FORMATS: dict[str, tuple[Reader, Writer | None]] = {
    "rmpl-toml": (read_rmpl_toml, write_rmpl_toml),
    "rmpl-json": (read_rmpl_json, write_rmpl_json),
    "anipose": (read_anipose, write_anipose),
    "panoptic": (read_panoptic, write_panoptic),
    "shelf4d": (read_shelf4d, write_shelf4d),
    "voxelpose": (read_voxelpose, write_voxelpose),
    "easymocap": (read_easymocap, write_easymocap),
    "h36m": (read_h36m, None),
    "h36m-pkl": (read_h36m_pkl, None),
    "qualisys": (read_qualisys, None),
}
