"""Shelf / Campus calibrations: 4D-association ``calibration.json`` and VoxelPose JSON."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.io.calibration._base import (
    CalibOptions,
    Source,
    load_json,
    make_camera,
    unit_scale,
)
from rmpl.io.calibration._serialise import json_dumps

log = logging.getLogger(__name__)


def read_shelf4d(path: Path, options: CalibOptions) -> Rig:
    """Read a 4D-association ``calibration.json`` (K 9, RT 12 row-major, metres)."""
    src, doc = Source(path), load_json(path)
    if not isinstance(doc, dict):
        raise InputError(path, None, "an object of cameras", type(doc).__name__)
    scale = unit_scale(path, options.units or "m")
    cams = []
    for key, cam in doc.items():
        K = src.intrinsics(
            src.array(cam, "K", key, (9,), "9 numbers (row-major 3x3)").reshape(3, 3), f"{key}.K"
        )
        RT = src.array(cam, "RT", key, (12,), "12 numbers (row-major 3x4 [R | t])").reshape(3, 4)
        R = src.rotation(RT[:, :3], f"{key}.RT")
        size = src.size(cam["imgSize"], f"{key}.imgSize") if "imgSize" in cam else None
        cams.append(make_camera(str(key), K, R, RT[:, 3] * scale, None, size))
    return src.rig(cams, "cameras")


def write_shelf4d(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """4D-association calibration JSON; refuses cameras with lens distortion."""
    scale = unit_scale(path, options.units or "m")
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
    return {path: json_dumps(doc)}


def read_voxelpose(path: Path, options: CalibOptions) -> Rig:
    """Read a VoxelPose Shelf/Campus calibration (T = camera centre, millimetres)."""
    src, doc = Source(path), load_json(path)
    if not isinstance(doc, dict):
        raise InputError(path, None, "an object of cameras", type(doc).__name__)
    scale = unit_scale(path, options.units or "mm")
    cams = []
    for key, cam in doc.items():
        fx, fy, cx, cy = (src.number(cam, k, key) for k in ("fx", "fy", "cx", "cy"))
        K = src.intrinsics(np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]), f"{key}.fx/fy")
        R = src.rotation(src.array(cam, "R", key, (3, 3), "a 3x3 matrix"), f"{key}.R")
        centre = src.array(cam, "T", key, (3,), "3 numbers (camera centre)") * scale
        k = src.array(cam, "k", key, (3,), "3 numbers (k1 k2 k3)")
        p = src.array(cam, "p", key, (2,), "2 numbers (p1 p2)")
        dist = np.array([k[0], k[1], p[0], p[1], k[2]])
        cams.append(make_camera(str(key), K, R, -R @ centre, dist, None))
    return src.rig(cams, "cameras")


def write_voxelpose(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """VoxelPose calibration JSON (T = centre in mm); drops image sizes, refuses skew."""
    scale = unit_scale(path, options.units or "mm")
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
    return {path: json_dumps(doc)}
