"""rmpl's own calibration, as TOML or as JSON (the layout is in :mod:`rmpl.io.calibration`)."""

from __future__ import annotations

from pathlib import Path

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig
from rmpl.io.calibration._base import (
    CONVENTION,
    CalibOptions,
    Source,
    load_json,
    load_toml,
    make_camera,
    unit_scale,
)
from rmpl.io.calibration._serialise import json_dumps, toml_dumps


def _read_rmpl_doc(src: Source, doc: object, options: CalibOptions) -> Rig:
    meta = src.table(doc, "metadata", "") if isinstance(doc, dict) and "metadata" in doc else {}
    units = options.units or meta.get("units", "m")
    scale = unit_scale(src.path, units, "metadata.units")
    cams = src.value(doc, "cameras", "", "a list of cameras")
    if not isinstance(cams, list):
        raise InputError(src.path, "cameras", "a list of cameras", type(cams).__name__)
    return src.rig([_read_rmpl_camera(src, c, f"cameras[{i}]", scale) for i, c in enumerate(cams)])


def _read_rmpl_camera(src: Source, cam: object, where: str, scale: float) -> Camera:
    name = src.value(cam, "name", where, "a camera name")
    K = src.intrinsics(src.array(cam, "K", where, (3, 3), "a 3x3 matrix"), f"{where}.K")
    R = src.rotation(src.array(cam, "R", where, (3, 3), "a 3x3 matrix"), f"{where}.R")
    t = src.array(cam, "t", where, (3,), "3 numbers") * scale
    dist = src.distortion(cam["dist"], f"{where}.dist") if "dist" in cam else None
    size = src.size(cam["size"], f"{where}.size") if "size" in cam else None
    return make_camera(str(name), K, R, t, dist, size)


def read_rmpl_toml(path: Path, options: CalibOptions) -> Rig:
    """Read rmpl's TOML calibration (see the module docstring)."""
    return _read_rmpl_doc(Source(path), load_toml(path), options)


def read_rmpl_json(path: Path, options: CalibOptions) -> Rig:
    """Read rmpl's JSON calibration (see the module docstring)."""
    return _read_rmpl_doc(Source(path), load_json(path), options)


def _rmpl_doc(rig: Rig, path: Path, options: CalibOptions) -> dict:
    units = options.units or "m"
    scale = unit_scale(path, units)
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
    return {path: "# rmpl camera calibration\n" + toml_dumps(_rmpl_doc(rig, path, options))}


def write_rmpl_json(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """rmpl's JSON calibration text for ``path``."""
    return {path: json_dumps(_rmpl_doc(rig, path, options))}
