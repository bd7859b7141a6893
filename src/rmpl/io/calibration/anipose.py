"""anipose / Pose2Sim TOML calibration: one table per camera, Rodrigues rotations."""

from __future__ import annotations

from pathlib import Path

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, rodrigues, rotation_to_rodrigues
from rmpl.io.calibration._base import (
    CalibOptions,
    Source,
    load_toml,
    make_camera,
    unit_scale,
)
from rmpl.io.calibration._serialise import toml_dumps


def read_anipose(path: Path, options: CalibOptions) -> Rig:
    """Read an anipose / Pose2Sim TOML calibration (translations in ``units``, default m)."""
    src, doc = Source(path), load_toml(path)
    meta = doc.get("metadata", {})
    units = options.units or (meta.get("units", "m") if isinstance(meta, dict) else "m")
    scale = unit_scale(path, units, "metadata.units")
    cams = [_read_anipose_camera(src, doc, key, scale) for key in doc if key != "metadata"]
    return src.rig(cams, "camera tables")


def _read_anipose_camera(src: Source, doc: dict, key: str, scale: float) -> Camera:
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
    return make_camera(str(cam.get("name", key)), K, rodrigues(rvec), t, dist, size)


def write_anipose(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """anipose / Pose2Sim TOML text; one table per camera, keyed by its name."""
    units = options.units or "m"
    scale = unit_scale(path, units)
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
    return {path: toml_dumps(doc)}
