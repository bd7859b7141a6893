"""Pinhole cameras with OpenCV lens distortion.

Conventions, written once here and used everywhere in rmpl:

- World -> camera: ``x_cam = R @ X + t`` (R a rotation, t in metres).
- Camera centre in the world: ``C = -R^T t``.
- Pixels are measured from the top-left corner of the image, x to the right, y down.
- Distortion is OpenCV's ``(k1, k2, p1, p2, k3)`` applied to normalised coordinates.
- Lengths are metres.

Shape glossary: ``V`` views, ``J`` joints, ``N`` points, ``*`` any leading dims.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

__all__ = [
    "Camera",
    "Rig",
    "project",
    "distort",
    "undistort",
    "undistort_points",
    "camera_centers",
    "rodrigues",
    "rotation_to_rodrigues",
    "look_at",
    "validate_rotation",
]


def _arr(x, shape: tuple[int, ...], what: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.shape != shape:
        raise ValueError(f"{what} must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be finite, got {a.tolist()}")
    return a


def validate_rotation(R: np.ndarray, what: str = "rotation", tol: float = 1e-3) -> np.ndarray:
    """Check that ``R`` (3, 3) is a proper rotation, to ``tol``; returns it as float."""
    R = _arr(R, (3, 3), what)
    err = np.abs(R @ R.T - np.eye(3)).max()
    if err > tol or np.linalg.det(R) < 0:
        raise ValueError(
            f"{what} is not a rotation matrix (|R R^T - I| = {err:.2e}, "
            f"det = {np.linalg.det(R):.3f}); expected an orthonormal 3x3 with det +1"
        )
    return R


@dataclass(frozen=True)
class Camera:
    """One calibrated camera.

    Attributes:
        K: intrinsic matrix, shape (3, 3), pixels.
        R: world->camera rotation, shape (3, 3).
        t: world->camera translation, shape (3,), metres.
        dist: OpenCV distortion (k1, k2, p1, p2, k3), shape (5,).
        size: image (width, height) in pixels, or None when unknown.
        name: camera name as in the calibration file.
    """

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    size: tuple[int, int] | None = None
    name: str = "cam"

    def __post_init__(self) -> None:
        object.__setattr__(self, "K", _arr(self.K, (3, 3), f"camera {self.name!r} K"))
        object.__setattr__(self, "R", validate_rotation(self.R, f"camera {self.name!r} rotation"))
        object.__setattr__(
            self, "t", _arr(np.ravel(self.t), (3,), f"camera {self.name!r} translation")
        )
        d = np.ravel(np.asarray(self.dist, dtype=float))
        if d.size > 5 or d.size not in (0, 4, 5):
            raise ValueError(
                f"camera {self.name!r} distortion must have 4 or 5 values "
                f"(k1 k2 p1 p2 [k3]), got {d.size}"
            )
        object.__setattr__(self, "dist", _arr(np.pad(d, (0, 5 - d.size)), (5,), "distortion"))
        if self.K[2, 2] == 0 or self.K[0, 0] <= 0 or self.K[1, 1] <= 0:
            raise ValueError(f"camera {self.name!r} K must have positive focal lengths")
        if self.size is not None:
            object.__setattr__(self, "size", (int(self.size[0]), int(self.size[1])))

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates, shape (3,), metres."""
        return -self.R.T @ self.t

    @property
    def P(self) -> np.ndarray:
        """Projection matrix K [R | t], shape (3, 4)."""
        return self.K @ np.concatenate([self.R, self.t[:, None]], axis=1)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Project world points, shape (*, 3), to pixels, shape (*, 2)."""
        return project(points, self.K, self.R, self.t, self.dist)

    def with_pose(self, R: np.ndarray, t: np.ndarray) -> Camera:
        return replace(self, R=R, t=t)


@dataclass(frozen=True)
class Rig:
    """An ordered set of cameras. Stacked parameters broadcast over views (V)."""

    cameras: tuple[Camera, ...]

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        if not cams:
            raise ValueError("a rig needs at least one camera")
        names = [c.name for c in cams]
        if len(set(names)) != len(names):
            raise ValueError(f"camera names must be unique, got {names}")
        object.__setattr__(self, "cameras", cams)

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self):
        return iter(self.cameras)

    def __getitem__(self, i):
        if isinstance(i, slice | list | tuple | np.ndarray):
            idx = np.arange(len(self))[i] if isinstance(i, slice) else i
            return Rig(tuple(self.cameras[int(j)] for j in idx))
        return self.cameras[i]

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.cameras]

    @property
    def K(self) -> np.ndarray:
        """Intrinsics, shape (V, 3, 3)."""
        return np.stack([c.K for c in self.cameras])

    @property
    def R(self) -> np.ndarray:
        """Rotations, shape (V, 3, 3)."""
        return np.stack([c.R for c in self.cameras])

    @property
    def t(self) -> np.ndarray:
        """Translations, shape (V, 3), metres."""
        return np.stack([c.t for c in self.cameras])

    @property
    def dist(self) -> np.ndarray:
        """Distortion coefficients, shape (V, 5)."""
        return np.stack([c.dist for c in self.cameras])

    @property
    def centers(self) -> np.ndarray:
        """Camera centres, shape (V, 3), metres."""
        return camera_centers(self.R, self.t)

    @property
    def sizes(self) -> np.ndarray:
        """Image (width, height), shape (V, 2); NaN where unknown."""
        return np.array([c.size if c.size else (np.nan, np.nan) for c in self.cameras], float)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Project world points, shape (*, N, 3), into every view: shape (*, V, N, 2)."""
        X = np.asarray(points, dtype=float)[..., None, :, :]  # (*, 1, N, 3)
        return project(X, self.K[:, None], self.R[:, None], self.t[:, None], self.dist[:, None])


def camera_centers(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Camera centres C = -R^T t. R: (*, 3, 3), t: (*, 3). Returns (*, 3)."""
    return -np.einsum("...ji,...j->...i", R, t)


def distort(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Apply OpenCV distortion to normalised coordinates.

    Args:
        xy: undistorted normalised image coordinates, shape (*, 2).
        dist: (k1, k2, p1, p2, k3), shape (*, 5), broadcast against ``xy``.

    Returns:
        Distorted normalised coordinates, shape (*, 2).
    """
    dist = np.asarray(dist, dtype=float)
    k1, k2, p1, p2, k3 = (dist[..., i] for i in range(5))
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], axis=-1)


def undistort(xy_d: np.ndarray, dist: np.ndarray, iterations: int = 12) -> np.ndarray:
    """Invert :func:`distort` by Newton's method on normalised coordinates.

    Args:
        xy_d: distorted normalised coordinates, shape (*, 2).
        dist: (k1, k2, p1, p2, k3), shape (*, 5), broadcast against ``xy_d``.
        iterations: Newton steps.

    Returns:
        Undistorted normalised coordinates, shape (*, 2).

    >>> import numpy as np
    >>> d = np.array([-0.2, 0.05, 1e-3, -1e-3, 0.0])
    >>> xy = np.array([[0.3, -0.2], [0.0, 0.0]])
    >>> bool(np.allclose(undistort(distort(xy, d), d), xy, atol=1e-12))
    True
    """
    dist = np.asarray(dist, dtype=float)
    if not np.any(dist):
        return np.asarray(xy_d, dtype=float).copy()
    k1, k2, p1, p2, k3 = (dist[..., i] for i in range(5))
    xy = np.array(xy_d, dtype=float, copy=True)
    for _ in range(iterations):
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dr = 2 * (k1 + r2 * (2 * k2 + 3 * k3 * r2))  # d radial / d(x or y), divided by x or y
        j00 = radial + x * x * dr + 2 * p1 * y + 6 * p2 * x
        j01 = x * y * dr + 2 * p1 * x + 2 * p2 * y
        j10 = x * y * dr + 2 * p1 * x + 2 * p2 * y
        j11 = radial + y * y * dr + 6 * p1 * y + 2 * p2 * x
        res = distort(xy, dist) - xy_d
        det = j00 * j11 - j01 * j10
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        dx = (j11 * res[..., 0] - j01 * res[..., 1]) / det
        dy = (-j10 * res[..., 0] + j00 * res[..., 1]) / det
        xy = xy - np.stack([dx, dy], axis=-1)
    return xy


def undistort_points(pixels: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Remove lens distortion from pixel coordinates.

    Args:
        pixels: shape (*, 2). K: (*, 3, 3). dist: (*, 5). Leading dims broadcast.

    Returns:
        Undistorted pixel coordinates, shape (*, 2), with the same K.
    """
    K = np.asarray(K, dtype=float)
    fx, fy, cx, cy, s = K[..., 0, 0], K[..., 1, 1], K[..., 0, 2], K[..., 1, 2], K[..., 0, 1]
    v = (pixels[..., 1] - cy) / fy
    u = (pixels[..., 0] - cx - s * v) / fx
    xy = undistort(np.stack([u, v], axis=-1), dist)
    return np.stack([fx * xy[..., 0] + s * xy[..., 1] + cx, fy * xy[..., 1] + cy], axis=-1)


def project(
    points: np.ndarray,
    K: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    dist: np.ndarray | None = None,
) -> np.ndarray:
    """Project world points to pixels: ``x = K distort((R X + t) / z)``.

    Args:
        points: world points, shape (*, 3), metres.
        K: (*, 3, 3). R: (*, 3, 3). t: (*, 3). dist: (*, 5) or None. All broadcast.

    Returns:
        Pixels, shape (*, 2). Points behind the camera (z <= 0) give NaN.

    >>> import numpy as np
    >>> K = np.array([[100.0, 0, 50], [0, 100, 40], [0, 0, 1]])
    >>> project(np.array([0.1, 0.2, 2.0]), K, np.eye(3), np.zeros(3)).tolist()
    [55.0, 50.0]
    """
    X = np.asarray(points, dtype=float)
    Xc = np.einsum("...ij,...j->...i", R, X) + t
    z = Xc[..., 2:3]
    xy = Xc[..., :2] / np.where(z > 0, z, np.nan)
    if dist is not None and np.any(dist):
        xy = distort(xy, dist)
    K = np.asarray(K, dtype=float)
    u = K[..., 0, 0] * xy[..., 0] + K[..., 0, 1] * xy[..., 1] + K[..., 0, 2]
    v = K[..., 1, 1] * xy[..., 1] + K[..., 1, 2]
    return np.stack([u, v], axis=-1)


def rodrigues(rvec: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle, radians), shape (*, 3), to matrix, shape (*, 3, 3).

    >>> import numpy as np
    >>> R = rodrigues(np.array([0.0, 0.0, np.pi / 2]))
    >>> np.round(R @ np.array([1.0, 0, 0]), 6).tolist()
    [0.0, 1.0, 0.0]
    """
    r = np.asarray(rvec, dtype=float)
    theta = np.linalg.norm(r, axis=-1, keepdims=True)
    k = r / np.where(theta > 1e-12, theta, 1.0)
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = np.zeros_like(kx)
    Kx = np.stack(
        [
            np.stack([zero, -kz, ky], -1),
            np.stack([kz, zero, -kx], -1),
            np.stack([-ky, kx, zero], -1),
        ],
        -2,
    )
    th = theta[..., None]
    return np.eye(3) + np.sin(th) * Kx + (1 - np.cos(th)) * (Kx @ Kx)


def rotation_to_rodrigues(R: np.ndarray) -> np.ndarray:
    """Rotation matrix, shape (*, 3, 3), to rotation vector, shape (*, 3)."""
    from scipy.spatial.transform import Rotation

    R = np.asarray(R, dtype=float)
    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec().reshape(*R.shape[:-2], 3)


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray | None = None):
    """World->camera (R, t) for a camera at ``eye`` looking at ``target``.

    The image y axis points along ``-up`` (so ``up`` appears at the top of the image).

    Args:
        eye: camera centres, shape (*, 3). target: (*, 3). up: (3,), default +z.

    Returns:
        R, shape (*, 3, 3), and t, shape (*, 3).
    """
    up = np.array([0.0, 0.0, 1.0]) if up is None else np.asarray(up, dtype=float)
    eye = np.asarray(eye, dtype=float)
    z = np.asarray(target, dtype=float) - eye
    z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    x = np.cross(z, np.broadcast_to(up, z.shape))
    n = np.linalg.norm(x, axis=-1, keepdims=True)
    # Looking straight along up: pick any perpendicular x.
    alt = np.cross(z, np.broadcast_to([1.0, 0.0, 0.0], z.shape))
    x = np.where(
        n > 1e-6, x / np.where(n > 1e-6, n, 1), alt / np.linalg.norm(alt, axis=-1, keepdims=True)
    )
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=-2)
    t = -np.einsum("...ij,...j->...i", R, eye)
    return R, t
