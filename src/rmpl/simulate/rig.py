"""The simulated rig: a preset laid out around the capture volume, or a user's calibration.

Presets (``rmpl simulate --rig NAME``) place ``cameras`` cameras around the origin, each
looking at a point ``aim`` metres above the centre of the floor:

- ``ring``: evenly on a circle of ``radius`` metres at ``height`` metres (the usual lab);
- ``arc``: on the half circle in front of the volume (a side line, a treadmill, a wall);
- ``corners``: high in the corners of a square room (``height`` + 0.8 m), looking down.

Every camera has the same pinhole (horizontal field of view ``fov`` degrees, or ``focal``
pixels), the principal point at the image centre, and the radial lens ``distortion``
(k1, k2) of a phone's main camera. A file given to ``--rig`` is read with
:func:`rmpl.io.calibration.load_rig` (any format rmpl reads, lenses included); it must give
each camera's image size.

Shape glossary: ``V`` cameras.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at

__all__ = ["PRESETS", "RigSpec", "build_rig", "fov_to_focal", "volume_of"]

#: Preset layouts (see the module docstring).
PRESETS = ("ring", "arc", "corners")


@dataclass(frozen=True)
class RigSpec:
    """What ``--rig`` and its options ask for.

    Attributes:
        rig: a preset name (:data:`PRESETS`) or a calibration file.
        cameras: cameras of a preset, 1 to 16.
        radius: metres from the volume's centre (a preset).
        height: camera height, metres (a preset).
        fov: horizontal field of view, degrees; or None when ``focal`` is given.
        focal: focal length, pixels; or None.
        resolution: (width, height) pixels.
        distortion: radial k1, k2 of every preset camera.
        aim: the height the cameras look at, metres.
    """

    rig: str = "ring"
    cameras: int = 4
    radius: float = 4.0
    height: float = 1.8
    fov: float | None = 65.0
    focal: float | None = None
    resolution: tuple[int, int] = (1920, 1080)
    distortion: tuple[float, float] = (-0.06, 0.02)
    aim: float = 1.0


def fov_to_focal(fov_deg: float, width: int) -> float:
    """The focal length in pixels of a horizontal field of view.

    >>> round(fov_to_focal(90.0, 1000), 3)
    500.0
    """
    return float(width / 2 / np.tan(np.radians(fov_deg) / 2))


def _check_spec(spec: RigSpec) -> None:
    w, h = spec.resolution
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise InputError(None, "--resolution", "WIDTHxHEIGHT within 16-8192 pixels", f"{w}x{h}")
    if not 1 <= spec.cameras <= 16:
        raise InputError(None, "--cameras", "1 to 16 cameras", spec.cameras)
    if not spec.radius > 0.5:
        raise InputError(None, "--radius", "a distance above 0.5 m", spec.radius)
    if not 0.1 <= spec.height <= 10:
        raise InputError(None, "--height", "a camera height of 0.1-10 m", spec.height)
    if spec.focal is None and not (10 <= (spec.fov or 0) <= 150):
        raise InputError(None, "--fov", "a horizontal field of view of 10-150 degrees", spec.fov)
    if spec.focal is not None and not spec.focal > 0:
        raise InputError(None, "--focal", "a focal length in pixels above 0", spec.focal)
    if not all(abs(k) < 1.0 for k in spec.distortion):
        raise InputError(None, "--distortion", "k1,k2 each within (-1, 1)", spec.distortion)


def _eyes(spec: RigSpec) -> np.ndarray:
    """The preset's camera centres (V, 3), metres."""
    V, r = spec.cameras, spec.radius
    if spec.rig == "ring":
        a = 2 * np.pi * np.arange(V) / V - np.pi / 2
        return np.stack([r * np.cos(a), r * np.sin(a), np.full(V, spec.height)], -1)
    if spec.rig == "arc":
        a = -np.pi / 2 + (np.linspace(-np.pi / 2, np.pi / 2, V) if V > 1 else np.zeros(1))
        return np.stack([r * np.cos(a), r * np.sin(a), np.full(V, spec.height)], -1)
    a = 2 * np.pi * np.arange(V) / V - 3 * np.pi / 4  # corners: 4 first, then between them
    d = r * np.sqrt(2) if V <= 4 else r
    return np.stack([d * np.cos(a), d * np.sin(a), np.full(V, spec.height + 0.8)], -1)


def build_rig(spec: RigSpec) -> Rig:
    """The rig ``spec`` asks for: a preset, or the cameras of a calibration file.

    Raises:
        InputError: an unknown preset that is not a file either, a file without image
            sizes, or options out of range.
    """
    if spec.rig not in PRESETS:
        path = Path(spec.rig)
        if not path.exists():
            raise InputError(
                path,
                "--rig",
                f"a calibration file or a preset, one of {', '.join(PRESETS)}",
                "neither",
            )
        from rmpl.io.calibration import load_rig

        rig = load_rig(path)
        missing = [c.name for c in rig if c.size is None]
        if missing:
            raise InputError(path, f"{missing[0]}.size", "each camera's image size", "missing")
        return rig
    _check_spec(spec)
    w, h = spec.resolution
    f = spec.focal if spec.focal is not None else fov_to_focal(spec.fov, w)
    K = np.array([[f, 0.0, (w - 1) / 2], [0.0, f, (h - 1) / 2], [0.0, 0.0, 1.0]])
    dist = np.array([spec.distortion[0], spec.distortion[1], 0.0, 0.0, 0.0])
    eyes = _eyes(spec)
    cams = []
    for v, eye in enumerate(eyes):
        R, t = look_at(eye, np.array([0.0, 0.0, spec.aim]))
        cams.append(Camera(K.copy(), R, t, dist.copy(), (w, h), name=f"cam{v + 1}"))
    return Rig(tuple(cams))


def volume_of(rig: Rig, height: float = 1.0, min_views: int = 2, step: float = 0.1):
    """The floor area where a body's middle (``height`` m up) is seen by ``min_views``
    cameras (or all of them, if fewer): (xs, ys, counts (len(ys), len(xs))).

    The grid spans the cameras' footprint; a point counts for a camera when it projects
    into the image with a 10% margin and lies in front of it.
    """
    c = rig.centers
    lo, hi = c[:, :2].min(0) - 1.0, c[:, :2].max(0) + 1.0
    xs = np.arange(lo[0], hi[0] + 1e-9, step)
    ys = np.arange(lo[1], hi[1] + 1e-9, step)
    gx, gy = np.meshgrid(xs, ys)
    pts = np.stack([gx, gy, np.full_like(gx, height)], -1).reshape(-1, 3)
    counts = np.zeros(len(pts), int)
    for cam in rig:
        x = pts @ cam.R.T + cam.t
        front = x[:, 2] > 0.3
        uv = cam.project(pts)
        w, h = cam.size
        inside = (
            (uv[:, 0] > 0.1 * w)
            & (uv[:, 0] < 0.9 * w)
            & (uv[:, 1] > 0.1 * h)
            & (uv[:, 1] < 0.9 * h)
        )
        counts += front & inside
    return xs, ys, counts.reshape(gx.shape)
