"""Keypoints to 3D rays (thesis section 3.3).

A keypoint at pixel (u, v) seen by camera (K, R, t, dist) is the ray with origin the camera
centre ``C = -R^T t`` and direction ``R^T K^-1 [u' v' 1]`` where (u', v') is the pixel after
lens undistortion. Directions are returned with unit length.
"""

from __future__ import annotations

import numpy as np

from rmpl.geometry.camera import Rig, camera_centers, undistort

__all__ = ["rays_from_keypoints", "closest_point_to_rays", "pixel_to_normalized"]


def pixel_to_normalized(pixels: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> np.ndarray:
    """Undistorted normalised image coordinates of pixels.

    Args:
        pixels: shape (*, 2). K: (*, 3, 3). dist: (*, 5) or None; broadcast.

    Returns:
        shape (*, 2): ``K^-1 [u v 1]`` after undistortion, z dropped.
    """
    K = np.asarray(K, dtype=float)
    fx, fy, cx, cy, s = K[..., 0, 0], K[..., 1, 1], K[..., 0, 2], K[..., 1, 2], K[..., 0, 1]
    y = (pixels[..., 1] - cy) / fy
    x = (pixels[..., 0] - cx - s * y) / fx
    xy = np.stack([x, y], axis=-1)
    if dist is not None and np.any(dist):
        xy = undistort(xy, dist)
    return xy


def rays_from_keypoints(
    keypoints: np.ndarray,
    rig: Rig | None = None,
    *,
    K: np.ndarray | None = None,
    R: np.ndarray | None = None,
    t: np.ndarray | None = None,
    dist: np.ndarray | None = None,
) -> np.ndarray:
    """3D rays of 2D keypoints.

    Args:
        keypoints: pixel coordinates, shape (*, V, J, 2). NaN stays NaN.
        rig: the V cameras; or pass K (*, V, 3, 3), R (*, V, 3, 3), t (*, V, 3) and
            optionally dist (*, V, 5) instead.

    Returns:
        Rays, shape (*, V, J, 6): origin (camera centre, metres) then unit direction.

    >>> import numpy as np
    >>> from rmpl.geometry.camera import Camera, Rig, look_at
    >>> R, t = look_at(np.array([0.0, -3, 1]), np.array([0.0, 0, 1]))
    >>> K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    >>> rig = Rig((Camera(K, R, t),))
    >>> ray = rays_from_keypoints(np.array([[[320.0, 240.0]]]), rig)[0, 0]
    >>> (np.round(ray, 6) + 0.0).tolist()
    [0.0, -3.0, 1.0, 0.0, 1.0, 0.0]
    """
    if rig is not None:
        K, R, t, dist = rig.K, rig.R, rig.t, rig.dist
    if K is None or R is None or t is None:
        raise ValueError("rays_from_keypoints needs a rig or K, R and t")
    kp = np.asarray(keypoints, dtype=float)
    if kp.ndim < 3 or kp.shape[-1] != 2:
        raise ValueError(f"keypoints must have shape (*, V, J, 2), got {kp.shape}")
    if K.shape[-3] != kp.shape[-3]:
        raise ValueError(
            f"keypoints have {kp.shape[-3]} views (axis -3) but the calibration has "
            f"{K.shape[-3]} cameras"
        )
    d = None if dist is None else np.asarray(dist)[..., None, :]
    xy = pixel_to_normalized(kp, K[..., None, :, :], d)  # (*, V, J, 2)
    dirs_cam = np.concatenate([xy, np.ones_like(xy[..., :1])], axis=-1)
    dirs = np.einsum("...vji,...vnj->...vni", R, dirs_cam)  # R^T d
    dirs = dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)
    origins = np.broadcast_to(camera_centers(R, t)[..., None, :], dirs.shape)
    return np.concatenate([origins, dirs], axis=-1)


def closest_point_to_rays(
    rays: np.ndarray, weights: np.ndarray | None = None, axis: int = -3
) -> np.ndarray:
    """Weighted least-squares point nearest to a set of rays.

    Args:
        rays: shape (*, V, J, 6) with unit directions (V along ``axis``).
        weights: shape (*, V, J); zero or NaN rays are ignored.

    Returns:
        Points, shape (*, J, 3); NaN where fewer than two non-parallel rays remain.
    """
    rays = np.moveaxis(np.asarray(rays, dtype=float), axis, -3)
    o, d = rays[..., :3], rays[..., 3:]
    w = (
        np.ones(rays.shape[:-1])
        if weights is None
        else np.moveaxis(np.asarray(weights, float), axis, -2)
    )
    ok = np.isfinite(rays).all(-1) & np.isfinite(w) & (w > 0)
    w = np.where(ok, w, 0.0)
    o, d = np.nan_to_num(o), np.nan_to_num(d)
    # sum_i w_i (I - d d^T) X = sum_i w_i (I - d d^T) o
    M = np.eye(3) - d[..., :, None] * d[..., None, :]  # (*, V, J, 3, 3)
    A = np.einsum("...vj,...vjab->...jab", w, M)
    b = np.einsum("...vj,...vjab,...vjb->...ja", w, M, o)
    enough = ok.sum(-2) >= 2
    cond = np.linalg.cond(np.where(enough[..., None, None], A, np.eye(3)))
    good = enough & (cond < 1e8)
    A = np.where(good[..., None, None], A, np.eye(3))
    X = np.linalg.solve(A, b[..., None])[..., 0]
    X[~good] = np.nan
    return X
