"""The floor: a plane ``n . X = d`` with a unit normal ``n`` pointing up, world metres.

One calibrated camera sees rays, not depths. A standing person's ankles rest a few
centimetres above the floor, so a known floor fixes where along the rays they stand
(:mod:`rmpl.pipeline.monocular`). The floor comes from the user (:func:`parse_floor`), the
calibration's convention (:func:`convention_floor`: a world axis up and the floor at 0, as
Shelf and Qualisys/Pose2Sim rigs have), or multi-view frames of the same rig
(:func:`fit_floor` on the lowest ankle of each triangulated person).

Everything here is a pure function on arrays; :func:`check_floor` refuses a floor that is
not a plane or lies above every camera, naming the field (:class:`rmpl.errors.InputError`).

Shape glossary: ``N`` points, ``V`` cameras, ``*`` any leading dims. Units: metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rmpl.errors import InputError

__all__ = [
    "ANKLE_HEIGHT",
    "AXES",
    "Floor",
    "check_floor",
    "convention_floor",
    "fit_floor",
    "parse_floor",
    "signed_distance",
]

#: Height of the ankle joint centre above the floor when standing, metres: 0.039 x stature
#: (Winter, *Biomechanics and Motor Control of Human Movement*, segment-length ratios),
#: 0.068 m for a 1.75 m adult, rounded to 0.07. The COCO ankle keypoint is this joint.
ANKLE_HEIGHT = 0.07

#: Axis names of ``--floor AXIS=H`` and ``--up``: name -> unit vector.
AXES = {
    "x": (1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "-x": (-1.0, 0.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "-z": (0.0, 0.0, -1.0),
}

#: Largest angle between a camera's image x axis and the horizontal of a world axis for the
#: calibration convention to apply (the camera's roll about that axis), degrees: a tripod
#: or handheld camera may lean (the Pose2Sim demo's cam_04 is rolled 24 degrees); a camera
#: looking straight down, or an unrelated world frame, is not taken for a floor.
CONVENTION_MAX_ANGLE = 30.0
#: A camera whose optical axis is within this many degrees of the up axis (straight down or
#: up) tells nothing about which axis is up: the convention is not assumed.
OVERHEAD_MIN_ANGLE = 15.0


@dataclass(frozen=True)
class Floor:
    """A floor plane ``normal . X = height``.

    Attributes:
        normal: unit normal pointing up (away from the floor, towards the cameras), (3,).
        height: offset ``d`` of the plane along ``normal``, metres (``z = 0``: 0).
        source: where it came from, for the run's log ("--floor z=0", "calibration
            convention", "estimated from N multi-view poses").
        spread: robust spread (1.48 MAD) of the points a fitted floor came from, metres;
            NaN when given.
    """

    normal: tuple[float, float, float]
    height: float
    source: str = "given"
    spread: float = float("nan")

    @property
    def n(self) -> np.ndarray:
        return np.asarray(self.normal, float)

    def describe(self) -> str:
        """``"0.000x +0.000y +1.000z = 0.000 m (given)"``."""
        nx, ny, nz = self.normal
        return f"{nx:.3f}x {ny:+.3f}y {nz:+.3f}z = {self.height:.3f} m ({self.source})"


def signed_distance(points: np.ndarray, floor: Floor) -> np.ndarray:
    """Height of points above the floor, metres (negative below), shape (*,).

    Args:
        points: (*, 3) world metres.

    >>> signed_distance(np.array([[0.0, 0.0, 1.5], [1.0, 2.0, -0.1]]), Floor((0, 0, 1), 0.0))
    array([ 1.5, -0.1])
    """
    return np.asarray(points, float) @ floor.n - floor.height


def _plane(values, field: str, path=None) -> Floor:
    """A :class:`Floor` from a normal and a height, normalised; InputError if not a plane."""
    n = np.asarray(values[:3], float)
    d = float(values[3])
    norm = float(np.linalg.norm(n)) if np.isfinite(n).all() else float("nan")
    if not (np.isfinite(norm) and norm > 1e-9 and np.isfinite(d)):
        raise InputError(
            path, field, "a plane: a finite, non-zero normal (nx, ny, nz) and a finite height d",
            [float(v) for v in values],
        )  # fmt: skip
    return Floor(tuple(float(v) for v in n / norm), d / norm)


def parse_floor(text: str, field: str = "--floor") -> Floor:
    """A floor from the command line.

    Accepted forms:

    - ``AXIS=H``: the floor is where coordinate AXIS equals H metres, and AXIS points up;
      AXIS is one of x, y, z, -x, -y, -z (``z=0``: z up, floor at z = 0; ``-y=0``: y down,
      floor at y = 0).
    - ``nx,ny,nz,d``: the plane ``n . X = d`` with ``n`` pointing up (normalised here).

    Raises:
        InputError: anything else, or a normal that is zero or not finite.

    >>> parse_floor("z=0").describe()
    '0.000x +0.000y +1.000z = 0.000 m (--floor z=0)'
    >>> parse_floor("0,0,2,1").height
    0.5
    """
    raw = text.strip().replace(" ", "")
    expected = "AXIS=H (AXIS one of x, y, z, -x, -y, -z; H in metres) or nx,ny,nz,d"
    if "=" in raw:
        axis, _, value = raw.partition("=")
        try:
            h = float(value)
        except ValueError:
            raise InputError(None, field, expected, text) from None
        if axis.lower() not in AXES:
            raise InputError(None, field, expected, text)
        floor = _plane([*AXES[axis.lower()], h], field)
    else:
        try:
            values = [float(v) for v in raw.split(",")]
        except ValueError:
            raise InputError(None, field, expected, text) from None
        if len(values) != 4:
            raise InputError(None, field, expected, text)
        floor = _plane(values, field)
    return Floor(floor.normal, floor.height, f"--floor {text.strip()}")


def check_floor(floor: Floor, centers: np.ndarray, field: str = "--floor", path=None) -> Floor:
    """Refuse a floor that is not a plane or that every camera is below.

    Args:
        floor: the plane.
        centers: camera centres (V, 3), world metres.

    Returns:
        The floor, unchanged.

    Raises:
        InputError: a non-unit or non-finite normal, a non-finite height, or all camera
            centres below (or on) the floor: the normal probably points down or the height
            is in other units.
    """
    n = np.asarray(floor.normal, float)
    if n.shape != (3,) or not np.isfinite(n).all() or abs(np.linalg.norm(n) - 1) > 1e-6:
        raise InputError(path, field, "a unit floor normal (nx, ny, nz)", floor.normal)
    if not np.isfinite(floor.height):
        raise InputError(path, field, "a finite floor height in metres", floor.height)
    above = signed_distance(np.asarray(centers, float).reshape(-1, 3), floor)
    if len(above) and not (above > 0).any():
        raise InputError(
            path, field,
            "a floor below the cameras, its normal pointing up towards them (camera heights "
            "above it must be > 0 m)",
            f"{floor.describe()}, camera heights {np.round(above, 2).tolist()} m",
        )  # fmt: skip
    return floor


def convention_floor(
    rotations: np.ndarray, centers: np.ndarray, up: np.ndarray | None = None
) -> Floor | None:
    """The calibration convention: a world axis up and the floor at 0 along it.

    The axis is the one nearest ``up`` when given, else nearest the cameras' mean image-up
    direction. The convention applies when every camera is upright about it (its image x
    axis within :data:`CONVENTION_MAX_ANGLE` degrees of horizontal: a small roll, any
    pitch, so one camera looking down is fine), none looks within
    :data:`OVERHEAD_MIN_ANGLE` degrees of straight along the axis (overhead: its roll says
    nothing), and all are above the plane; otherwise None (no floor is assumed).

    Args:
        rotations: world-to-camera rotations (V, 3, 3).
        centers: camera centres (V, 3), metres.
        up: the world up direction (3,), or None.

    >>> from rmpl.geometry.camera import look_at
    >>> R, t = look_at(np.array([5.0, 0.0, 2.5]), np.array([0.0, 0.0, 1.0]))  # 17 deg down
    >>> convention_floor(R[None], np.array([[5.0, 0.0, 2.5]])).normal
    (0.0, 0.0, 1.0)
    """
    R = np.asarray(rotations, float).reshape(-1, 3, 3)
    hint = -R[:, 1, :].sum(0) if up is None else np.asarray(up, float)
    if not np.isfinite(hint).all() or not np.linalg.norm(hint) > 0:
        return None
    name, axis = max(AXES.items(), key=lambda kv: float(np.dot(kv[1], hint)))
    tilt = np.degrees(np.arcsin(np.clip(np.abs(R[:, 0, :] @ np.asarray(axis)), 0, 1)))
    if (tilt > CONVENTION_MAX_ANGLE).any():
        return None
    # A camera looking nearly along the axis (straight down or up) has a horizontal image x
    # axis for any axis: its roll says nothing, and its image-up may lie on a wall.
    along = np.degrees(np.arccos(np.clip(np.abs(R[:, 2, :] @ np.asarray(axis)), 0, 1)))
    if (along < OVERHEAD_MIN_ANGLE).any():
        return None
    floor = Floor(axis, 0.0, f"calibration convention: {name} up, floor at {name.lstrip('-')} = 0")
    if not (signed_distance(np.asarray(centers, float).reshape(-1, 3), floor) > 0).all():
        return None
    return floor


def fit_floor(
    points: np.ndarray,
    up: np.ndarray,
    contact_height: float = ANKLE_HEIGHT,
    tilt: bool = True,
    max_tilt: float = 10.0,
) -> Floor:
    """The floor under contact points: a plane ``contact_height`` below them.

    ``points`` are the lowest ankle of people standing or walking (one per person and
    frame, from multi-view triangulation); most rest on the floor, a few are lifted (swing,
    jumps) or wrong. The height is the median of their heights along ``up`` minus
    ``contact_height``. With ``tilt`` and points spread at least 1 m in two horizontal
    directions, the normal is refitted (iteratively reweighted total least squares); the
    fit is kept when within ``max_tilt`` degrees of ``up``.

    Args:
        points: (N, 3) world metres; rows with NaN are ignored.
        up: the world up direction (3,), e.g. from the cameras.
        contact_height: ankle height above the floor when standing, metres.

    Returns:
        The :class:`Floor` with its ``spread`` (1.48 MAD of the heights, metres).

    Raises:
        InputError: fewer than 10 finite points.
    """
    p = np.asarray(points, float).reshape(-1, 3)
    p = p[np.isfinite(p).all(-1)]
    if len(p) < 10:
        raise InputError(None, "floor", "at least 10 ankle positions to fit the floor", len(p))
    n = np.asarray(up, float) / np.linalg.norm(up)
    if tilt:
        n = _refit_normal(p, n, max_tilt)
    h = p @ n
    level = float(np.median(h))
    spread = 1.4826 * float(np.median(np.abs(h - level)))
    source = f"estimated from {len(p)} ankle positions (spread {100 * spread:.1f} cm)"
    return Floor(tuple(float(v) for v in n), level - contact_height, source, spread)


def _refit_normal(p: np.ndarray, up: np.ndarray, max_tilt: float) -> np.ndarray:
    """The normal of the plane through ``p`` (N, 3), or ``up`` when the points are too
    little spread or the plane tilts more than ``max_tilt`` degrees from it."""
    centred = p - np.median(p, 0)
    flat = centred - np.outer(centred @ up, up)  # the horizontal spread
    sv = np.linalg.svd(flat, compute_uv=False)
    if sv[1] / np.sqrt(len(p)) < 0.3:  # < about 1 m of extent in the second direction
        return up
    n, w = up, np.ones(len(p))
    for _ in range(10):  # IRLS: down-weight points far from the current plane
        c = (w[:, None] * p).sum(0) / w.sum()
        q = (p - c) * np.sqrt(w)[:, None]
        n = np.linalg.svd(q, full_matrices=False)[2][-1]
        n = n if n @ up >= 0 else -n
        r = np.abs((p - c) @ n)
        scale = max(1.4826 * np.median(r), 1e-3)
        w = 1.0 / np.maximum(1.0, r / (2 * scale))  # Huber-like
    if np.degrees(np.arccos(np.clip(n @ up, -1, 1))) > max_tilt:
        return up
    return n
