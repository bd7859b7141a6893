"""Qualisys ``.qca.txt`` XML (read only), interpreted as Pose2Sim does."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig
from rmpl.io.calibration._base import (
    CalibOptions,
    Source,
    make_camera,
    read_text,
    unit_scale,
)

_QUALISYS_VIDEO_MODELS = ("Miqus Video", "Miqus Video UnderWater", "none")


def read_qualisys(path: Path, options: CalibOptions) -> Rig:
    """Read a Qualisys ``.qca.txt`` the way Pose2Sim interprets it (positions in mm)."""
    text = read_text(path)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise InputError(path, None, "valid XML", str(e)) from None
    binning = options.binning_factor
    if not isinstance(binning, int) or binning < 1:
        raise InputError(path, "binning_factor", "a positive integer", binning)
    scale = unit_scale(path, options.units or "mm")
    elems = [
        c
        for c in root.findall("cameras/camera")
        if c.get("model", "none") in _QUALISYS_VIDEO_MODELS
    ]
    src = Source(path)
    cams = [_read_qualisys_camera(src, e, i, binning, scale) for i, e in enumerate(elems)]
    cams.sort(key=lambda c: _natural_key(c.name))
    return src.rig(cams, "cameras/camera")


def _natural_key(name: str) -> list:
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", name)]


def _xml_numbers(
    src: Source, parent: ET.Element, tag: str, where: str, names: tuple[str, ...]
) -> dict[str, float]:
    elem = parent.find(tag)
    if elem is None:
        raise InputError(src.path, f"{where}.{tag}", f"a <{tag}> element", "nothing")
    return {n: float(src.array(elem.attrib, n, f"{where}.{tag}", (), "a number")) for n in names}


def _read_qualisys_camera(
    src: Source, elem: ET.Element, index: int, binning: int, scale: float
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
    return make_camera(name, K, R, -R @ centre, dist, size)


def _qualisys_resolution(src: Source, elem: ET.Element, where: str) -> int:
    """Video lines: the ``video_resolution`` attribute ("1080p", "720p", ...), else 1080."""
    text = elem.get("video_resolution")
    if text is None:
        return 1080
    m = re.fullmatch(r"\s*(\d+)\s*[pP]?\s*", text)
    if m is None or int(m[1]) == 0:
        raise InputError(src.path, f"{where}.video_resolution", "a resolution like '1080p'", text)
    return int(m[1])
