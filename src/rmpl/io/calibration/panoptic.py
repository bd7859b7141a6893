"""CMU Panoptic ``calibration_<seq>.json``: translations in centimetres, typed cameras."""

from __future__ import annotations

import re
from pathlib import Path

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig
from rmpl.io.calibration._base import (
    CAMERA_TYPES,
    CalibOptions,
    Source,
    load_json,
    make_camera,
    unit_scale,
)
from rmpl.io.calibration._serialise import json_dumps


def read_panoptic(path: Path, options: CalibOptions) -> Rig:
    """Read a CMU Panoptic ``calibration_<seq>.json`` (t in cm), keeping ``camera_type``."""
    src, doc = Source(path), load_json(path)
    if options.camera_type not in CAMERA_TYPES:
        raise InputError(path, "camera_type", f"one of {list(CAMERA_TYPES)}", options.camera_type)
    scale = unit_scale(path, options.units or "cm")
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


def _read_panoptic_camera(src: Source, cam: dict, where: str, scale: float) -> Camera:
    name = src.value(cam, "name", where, "a camera name")
    K = src.intrinsics(src.array(cam, "K", where, (3, 3), "a 3x3 matrix"), f"{where}.K")
    dist = src.distortion(src.value(cam, "distCoef", where, "5 numbers"), f"{where}.distCoef")
    R = src.rotation(src.array(cam, "R", where, (3, 3), "a 3x3 matrix"), f"{where}.R")
    t = src.array(cam, "t", where, (3,), "3 numbers") * scale
    size = src.size(cam["resolution"], f"{where}.resolution") if "resolution" in cam else None
    return make_camera(str(name), K, R, t, dist, size)


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
    scale = unit_scale(path, options.units or "cm")
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
    return {path: json_dumps({"calibDataSource": "rmpl", "cameras": cams})}
