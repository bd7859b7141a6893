"""Random camera setups (the thesis's RCS): where MHP puts its virtual cameras.

Every camera is an upright pinhole (small roll, no distortion) aimed at the person with a
jitter, so the person's centre lands inside the image. Conventions are rmpl's
(:mod:`rmpl.geometry.camera`): world -> camera ``x = R X + t``, metres, pixels from the
top-left corner, z-up world.

Two kinds of placement:

- ``"box"``: camera centres uniform in a fixed world box (the Human3.6M room of the thesis,
  centred on the world origin), at least ``min_distance`` from the person.
- ``"orbit"``: camera centres at a random azimuth around the person, a horizontal distance in
  ``distance`` and an absolute height in ``height`` (a dome or a room's walls).

Shape glossary: ``B`` persons (any leading dims of ``person_center``), ``V`` cameras per person.
Pure numpy: the trainer samples cameras on the fly with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rmpl.geometry.camera import look_at, project

__all__ = [
    "CameraPreset",
    "CAMERA_PRESETS",
    "sample_cameras",
    "horizontal_fov_to_focal",
    "sphere_cameras",
]

_COMMON_SIZES = (
    (640, 480),
    (800, 600),
    (1000, 1000),
    (1024, 768),
    (1032, 776),
    (1280, 720),
    (1280, 960),
    (1440, 1080),
    (1600, 1200),
    (1920, 1080),
)


@dataclass(frozen=True)
class CameraPreset:
    """Ranges a random camera is drawn from. Every range is ``(low, high)``, uniform.

    Attributes:
        name: key in :data:`CAMERA_PRESETS`.
        placement: ``"box"`` (centres in ``box``, world metres) or ``"orbit"`` (around the
            person at a horizontal ``distance`` and absolute ``height``, metres).
        box: ``((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi))`` for ``"box"``.
        distance: horizontal camera-to-person distance for ``"orbit"``, metres.
        height: camera height above the floor (z = 0) for ``"orbit"``, metres.
        min_distance: smallest 3D camera-to-person distance, metres.
        sizes: image sizes ``(width, height)`` in pixels, drawn uniformly.
        focal: focal length in pixels, or None to use ``fov``.
        fov: horizontal field of view in degrees, used when ``focal`` is None.
        principal_jitter: principal point offset from the image centre, uniform in
            ``[-j, j]`` pixels on each axis.
        aim_jitter: the aim point is the person centre plus uniform ``[-j, j]`` metres per axis.
        roll: camera roll about its optical axis, uniform ``[-r, r]`` degrees.
        margin: the person centre must project at least this fraction of the image size
            away from the border (samples that miss it are redrawn).
    """

    name: str
    placement: str
    box: tuple[tuple[float, float], ...] | None = None
    distance: tuple[float, float] | None = None
    height: tuple[float, float] | None = None
    min_distance: float = 1.5
    sizes: tuple[tuple[int, int], ...] = ((1000, 1000),)
    focal: tuple[float, float] | None = None
    fov: tuple[float, float] | None = None
    principal_jitter: float = 10.0
    aim_jitter: float = 0.3
    roll: float = 3.0
    margin: float = 0.1

    def __post_init__(self) -> None:
        if self.placement == "box":
            if self.box is None or np.shape(self.box) != (3, 2):
                raise ValueError(f"preset {self.name!r}: 'box' placement needs box (3, 2)")
        elif self.placement == "orbit":
            if self.distance is None or self.height is None:
                raise ValueError(f"preset {self.name!r}: 'orbit' needs distance and height")
        else:
            raise ValueError(
                f"preset {self.name!r}: placement must be 'box' or 'orbit', got {self.placement!r}"
            )
        if (self.focal is None) == (self.fov is None):
            raise ValueError(f"preset {self.name!r}: give exactly one of focal and fov")
        if not 0 <= self.margin < 0.5:
            raise ValueError(f"preset {self.name!r}: margin must be in [0, 0.5), got {self.margin}")


CAMERA_PRESETS: dict[str, CameraPreset] = {
    # Thesis / FACTS.md: centres uniform in x [-2.2, 2.2], y [-5.2, 5.2], z [1, 2] m, aimed
    # at the person +-0.5 m, Human3.6M intrinsics (fx ~1145 px, 1000x1000).
    "h36m": CameraPreset(
        "h36m",
        "box",
        box=((-2.2, 2.2), (-5.2, 5.2), (1.0, 2.0)),
        min_distance=2.0,
        sizes=((1000, 1000),),
        focal=(1140.0, 1150.0),
        principal_jitter=15.0,
        aim_jitter=0.5,
        roll=2.0,
    ),
    # CMU Panoptic HD cameras: a dome of radius ~3 m, 1920x1080, fx 1400-1700 px.
    "panoptic": CameraPreset(
        "panoptic",
        "orbit",
        distance=(2.5, 3.5),
        height=(0.5, 2.5),
        min_distance=2.0,
        sizes=((1920, 1080),),
        focal=(1400.0, 1700.0),
        principal_jitter=20.0,
        aim_jitter=0.3,
        roll=3.0,
    ),
    # Shelf / Campus: 1032x776, fx ~1050-1150 px, 2.5-5 m away, mounted 1.5-3 m high.
    "shelf": CameraPreset(
        "shelf",
        "orbit",
        distance=(2.5, 5.0),
        height=(1.5, 3.0),
        min_distance=2.5,
        sizes=((1032, 776),),
        focal=(1050.0, 1150.0),
        principal_jitter=20.0,
        aim_jitter=0.3,
        roll=3.0,
    ),
    # Anything a user may have: 1.5-8 m, 0.3-4 m high, 35-90 deg horizontal FOV.
    "universal": CameraPreset(
        "universal",
        "orbit",
        distance=(1.5, 8.0),
        height=(0.3, 4.0),
        min_distance=1.5,
        sizes=_COMMON_SIZES,
        fov=(35.0, 90.0),
        principal_jitter=20.0,
        aim_jitter=0.3,
        roll=5.0,
    ),
}


def horizontal_fov_to_focal(fov_deg: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Focal length in pixels for a horizontal field of view (degrees) and image width (pixels).

    >>> round(float(horizontal_fov_to_focal(90.0, 1000)), 6)
    500.0
    """
    return 0.5 * np.asarray(width, float) / np.tan(np.radians(np.asarray(fov_deg, float)) / 2)


def _uniform(rng: np.random.Generator, lo_hi, shape) -> np.ndarray:
    lo, hi = lo_hi
    return rng.uniform(lo, hi, shape)


def _draw(preset: CameraPreset, center: np.ndarray, rng: np.random.Generator):
    """One unchecked draw for every row of ``center`` (N, 3): K, R, t, size."""
    n = center.shape[0]
    if preset.placement == "box":
        lo, hi = np.asarray(preset.box, float).T
        eye = rng.uniform(lo, hi, (n, 3))
    else:
        azimuth = rng.uniform(0.0, 2 * np.pi, n)
        radius = _uniform(rng, preset.distance, n)
        eye = np.stack(
            [
                center[:, 0] + radius * np.cos(azimuth),
                center[:, 1] + radius * np.sin(azimuth),
                _uniform(rng, preset.height, n),
            ],
            axis=-1,
        )
    target = center + rng.uniform(-preset.aim_jitter, preset.aim_jitter, (n, 3))
    R, t = look_at(eye, target)
    roll = np.radians(rng.uniform(-preset.roll, preset.roll, n))
    c, s, zero, one = np.cos(roll), np.sin(roll), np.zeros(n), np.ones(n)
    Rz = np.stack(
        [np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)],
        -2,
    )  # (N, 3, 3) roll about the optical axis, applied in the camera frame
    R, t = Rz @ R, np.einsum("nij,nj->ni", Rz, t)

    sizes = np.asarray(preset.sizes, dtype=np.int64)
    size = sizes[rng.integers(0, len(sizes), n)]  # (N, 2) width, height
    if preset.focal is not None:
        f = _uniform(rng, preset.focal, n)
    else:
        f = horizontal_fov_to_focal(_uniform(rng, preset.fov, n), size[:, 0])
    pp = size / 2.0 + rng.uniform(-preset.principal_jitter, preset.principal_jitter, (n, 2))
    K = np.zeros((n, 3, 3))
    K[:, 0, 0], K[:, 1, 1], K[:, 2, 2] = f, f, 1.0
    K[:, :2, 2] = pp
    return K, R, t, size, eye


def _acceptable(preset: CameraPreset, center, K, R, t, size, eye) -> np.ndarray:
    uv = project(center, K, R, t)  # (N, 2), NaN behind the camera
    lo, hi = preset.margin * size, (1 - preset.margin) * size
    with np.errstate(invalid="ignore"):
        inside = np.all((uv >= lo) & (uv <= hi), axis=-1)
    far = np.linalg.norm(eye - center, axis=-1) >= preset.min_distance
    return inside & far


def sample_cameras(
    num: int,
    person_center: np.ndarray,
    preset: str | CameraPreset = "universal",
    rng: np.random.Generator | int | None = None,
    max_tries: int = 100,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Draw ``num`` random cameras looking at each person.

    Args:
        num: cameras per person, V.
        person_center: the point to aim at (e.g. the pelvis), shape (*, 3), world metres,
            z up with the floor at z = 0. For the ``"h36m"`` preset, in the room frame whose
            origin is the room centre.
        preset: a key of :data:`CAMERA_PRESETS` or a :class:`CameraPreset`.
        rng: a numpy Generator, or a seed.
        max_tries: redraw rounds for cameras that are too close or miss the person.

    Returns:
        K, shape (*, V, 3, 3), pixels; R, shape (*, V, 3, 3); t, shape (*, V, 3), metres;
        size, shape (*, V, 2), int (width, height) in pixels.

    Raises:
        ValueError: on an unknown preset or a bad ``person_center``; RuntimeError when no
            valid camera is found for some person within ``max_tries`` rounds (e.g. a person
            far outside the ``"h36m"`` camera box).

    >>> K, R, t, size = sample_cameras(4, [0.0, 0.0, 1.0], "h36m", rng=0)
    >>> K.shape, R.shape, t.shape, size.shape
    ((4, 3, 3), (4, 3, 3), (4, 3), (4, 2))
    """
    preset = _preset(preset)
    if num < 1:
        raise ValueError(f"num must be >= 1, got {num}")
    center = np.asarray(person_center, dtype=float)
    if center.ndim < 1 or center.shape[-1] != 3 or not np.all(np.isfinite(center)):
        raise ValueError(f"person_center must be finite with shape (*, 3), got {center.shape}")
    rng = np.random.default_rng(rng)

    flat = np.repeat(center.reshape(-1, 3), num, axis=0)  # (B * V, 3) one row per camera
    K, R, t, size = _draw_valid(preset, flat, rng, max_tries)
    shape = (*center.shape[:-1], num)
    return (
        K.reshape(*shape, 3, 3),
        R.reshape(*shape, 3, 3),
        t.reshape(*shape, 3),
        size.reshape(*shape, 2),
    )


def _preset(preset: str | CameraPreset) -> CameraPreset:
    """The preset of that name in :data:`CAMERA_PRESETS`, or ``preset`` itself."""
    if isinstance(preset, str):
        if preset not in CAMERA_PRESETS:
            raise ValueError(f"unknown camera preset {preset!r}; known: {sorted(CAMERA_PRESETS)}")
        preset = CAMERA_PRESETS[preset]
    return preset


def _draw_valid(preset: CameraPreset, center: np.ndarray, rng: np.random.Generator, max_tries: int):
    """One acceptable camera per row of ``center`` (N, 3), redrawing the rejected ones.

    Returns:
        K (N, 3, 3), R (N, 3, 3), t (N, 3) and size (N, 2) int.
    """
    n = center.shape[0]
    K, R, t = np.zeros((n, 3, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3))
    size = np.zeros((n, 2), dtype=np.int64)
    todo = np.arange(n)
    for _ in range(max_tries):
        draw = _draw(preset, center[todo], rng)
        ok = _acceptable(preset, center[todo], *draw)
        idx = todo[ok]
        K[idx], R[idx], t[idx], size[idx] = (a[ok] for a in draw[:4])
        todo = todo[~ok]
        if todo.size == 0:
            return K, R, t, size
    raise RuntimeError(
        f"preset {preset.name!r}: no valid camera for {todo.size} of {n} draws after "
        f"{max_tries} tries; is the person centre {center[todo[0]].tolist()} inside the scene?"
    )


def sphere_cameras(
    height: float,
    azimuths_deg,
    radius: float = 6.0,
    center=(0.0, 0.0, 1.0),
    focal: float = 1145.0,
    size: tuple[int, int] = (1000, 1000),
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cameras on a sphere around a person, all at one height, aimed at the sphere's centre.

    The camera-geometry experiment of the thesis (6.14): two cameras ``radius`` metres
    from the person at an absolute height, the horizontal angle between them swept.

    Args:
        height: camera height above the floor (z = 0), metres.
        azimuths_deg: horizontal direction of each camera seen from the centre, degrees,
            shape (V,).
        radius: distance of every camera centre from ``center``, metres.
        center: the sphere's centre and aim point (e.g. a standing person's pelvis),
            world metres, z up.
        focal: focal length, pixels (default: Human3.6M's ~1145 px).
        size: image (width, height), pixels; the principal point is its centre.

    Returns:
        K, shape (V, 3, 3), pixels; R, shape (V, 3, 3); t, shape (V, 3), metres; size,
        shape (V, 2), int.

    Raises:
        ValueError: when the height is out of the sphere's reach or nothing is given.

    >>> K, R, t, wh = sphere_cameras(2.2, [0.0, 90.0])
    >>> centres = -np.einsum("vji,vj->vi", R, t)
    >>> np.round(np.linalg.norm(centres - [0, 0, 1.0], axis=1), 6).tolist()
    [6.0, 6.0]
    >>> np.round(centres[:, 2], 6).tolist()
    [2.2, 2.2]
    """
    az = np.radians(np.atleast_1d(np.asarray(azimuths_deg, dtype=float)))
    c = np.asarray(center, dtype=float)
    if az.ndim != 1 or az.size == 0 or not np.all(np.isfinite(az)):
        raise ValueError(f"azimuths_deg must be finite with shape (V,), got {np.shape(az)}")
    if c.shape != (3,) or not radius > 0 or not focal > 0:
        raise ValueError("center must have shape (3,), radius and focal must be > 0")
    dz = float(height) - c[2]
    if not abs(dz) < radius:
        raise ValueError(
            f"camera height {height} m is out of reach of a {radius} m sphere centred at "
            f"z = {c[2]} m"
        )
    horizontal = np.sqrt(radius**2 - dz**2)
    eye = np.stack(
        [c[0] + horizontal * np.cos(az), c[1] + horizontal * np.sin(az), np.full(az.size, height)],
        axis=-1,
    )
    R, t = look_at(eye, np.broadcast_to(c, eye.shape))
    V = az.size
    K = np.zeros((V, 3, 3))
    K[:, 0, 0] = K[:, 1, 1] = focal
    K[:, 0, 2], K[:, 1, 2], K[:, 2, 2] = size[0] / 2.0, size[1] / 2.0, 1.0
    return K, R, t, np.tile(np.asarray(size, dtype=np.int64), (V, 1))
