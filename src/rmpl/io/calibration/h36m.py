"""Human3.6M calibrations (read only): ``camera-parameters.json`` and mmpose's ``cameras.pkl``."""

from __future__ import annotations

import importlib.util
import io
import pickle
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig
from rmpl.io.calibration._base import (
    CalibOptions,
    Source,
    load_json,
    make_camera,
    unit_scale,
)

# Image sizes of the four Human3.6M cameras (width, height), pixels.
_H36M_SIZES = {
    "54138969": (1000, 1002),
    "55011271": (1000, 1000),
    "58860488": (1000, 1000),
    "60457274": (1000, 1002),
}


def read_h36m(path: Path, options: CalibOptions) -> Rig:
    """Read H36M ``camera-parameters.json`` for ``options.subject`` (t in mm)."""
    src, doc = Source(path), load_json(path)
    scale = unit_scale(path, options.units or "mm")
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
        cams.append(make_camera(str(cam_id), K, R, t, dist, _H36M_SIZES.get(str(cam_id))))
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
    try:
        data = path.read_bytes()
    except OSError as e:
        raise InputError(path, None, "a readable file", e.strerror or type(e).__name__) from None
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
    src, doc = Source(path), load_plain_pickle(path)
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
    scale = unit_scale(path, options.units or "m")
    return src.rig([_read_h36m_pkl_camera(src, doc[k], f"{k}", scale) for k in keys])


def _read_h36m_pkl_camera(src: Source, cam: object, where: str, scale: float) -> Camera:
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
    return make_camera(name, K, R, -R @ centre, dist, size)
