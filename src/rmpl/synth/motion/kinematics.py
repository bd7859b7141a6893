"""Forward kinematics: Euler angles to rotations, ASF and BVH joint chains to positions
and rest-relative rotations, and units and axes into rmpl's z-up metres."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.synth.motion._common import (
    LENGTH_UNITS,
    PLAUSIBLE_REST_HEIGHT,
    TYPICAL_REST_HEIGHT,
    Y_UP_TO_Z_UP,
)

_log = logging.getLogger(__name__)


def _euler(angles: np.ndarray, axes: str, fixed: bool) -> np.ndarray:
    """Rotation from Euler angles, shape (*, K) radians about ``axes`` (K letters) -> (*, 3, 3).

    ``fixed``: the first listed rotation acts first about the fixed parent axes (Acclaim),
    so R = R_K ... R_1. Otherwise the axes move with the joint (BVH): R = R_1 ... R_K.
    Rotations are right-handed (counter-clockwise looking down the axis).

    >>> x, angles = np.array([1.0, 0.0, 0.0]), np.radians([90.0, 90.0])
    >>> (np.round(_euler(angles, "xz", fixed=True) @ x, 6) + 0.0).tolist()  # Rz Rx x = y
    [0.0, 1.0, 0.0]
    >>> (np.round(_euler(angles, "xz", fixed=False) @ x, 6) + 0.0).tolist()  # Rx Rz x = z
    [0.0, 0.0, 1.0]
    """
    angles = np.asarray(angles, dtype=float)
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for n, axis in enumerate(axes):
        i = "xyz".index(axis)
        j, k = (i + 1) % 3, (i + 2) % 3
        c, s = np.cos(angles[..., n, None]), np.sin(angles[..., n, None])  # (*, 1)
        if fixed:  # R <- R_axis @ R mixes rows j and k
            rj, rk = R[..., j, :].copy(), R[..., k, :].copy()
            R[..., j, :], R[..., k, :] = c * rj - s * rk, s * rj + c * rk
        else:  # R <- R @ R_axis mixes columns j and k
            cj, ck = R[..., :, j].copy(), R[..., :, k].copy()
            R[..., :, j], R[..., :, k] = c * cj + s * ck, c * ck - s * cj
    return R


# ---------------------------------------------------------------------- units and axes


def detect_length_unit(height: float) -> tuple[str, float]:
    """The unit of :data:`LENGTH_UNITS` that makes a rest pose of ``height`` file units
    closest (in ratio) to :data:`TYPICAL_REST_HEIGHT`. Returns (name, metres per unit).

    >>> detect_length_unit(172.0), detect_length_unit(66.0)
    (('cm', 0.01), ('inch', 0.0254))
    """
    if not height > 0:
        raise ValueError(f"height must be positive, got {height}")
    name = min(
        LENGTH_UNITS, key=lambda u: abs(math.log(height * LENGTH_UNITS[u] / TYPICAL_REST_HEIGHT))
    )
    return name, LENGTH_UNITS[name]


def _checked_scale(
    path: Path, height: float, stated: float | None, override: float | None
) -> float:
    """Metres per file unit: ``override``, else the file's stated unit, else detected; the
    rest height (file units) must then be human."""
    lo, hi = PLAUSIBLE_REST_HEIGHT
    if override is not None:
        return override
    if stated is not None and lo <= height * stated <= hi:
        return stated
    if stated is not None:
        _log.warning(
            "%s: stated unit gives a %.2f m rest pose; detecting the unit", path, height * stated
        )
    if height <= 0:
        raise InputError(path, "rest pose", "a skeleton with some height", height)
    name, scale = detect_length_unit(height)
    if not lo <= height * scale <= hi:
        raise InputError(
            path,
            "length unit",
            f"a rest pose {lo}-{hi} m tall in one of {sorted(LENGTH_UNITS)} (pass scale=)",
            f"{height:.4g} file units",
        )
    _log.debug("%s: length unit %s (rest height %.2f m)", path, name, height * scale)
    return scale


def _axis_map(up: str) -> tuple[np.ndarray, np.ndarray]:
    """The file-to-world axis rotation as a signed permutation: world axis i = sign[i] *
    file axis perm[i]."""
    A = Y_UP_TO_Z_UP if up == "y" else np.eye(3)
    perm = np.abs(A).argmax(axis=1)
    return perm, A[np.arange(3), perm]


def _points_z_up(P: np.ndarray, scale: float, up: str) -> np.ndarray:
    """File positions, shape (*, 3) -> metres, z up."""
    perm, sign = _axis_map(up)
    return P[..., perm] * (sign * scale)


def _rotations_z_up(R: np.ndarray, up: str) -> np.ndarray:
    """Rest-relative rotations in file axes, shape (*, 3, 3) -> z-up axes (A R A^T)."""
    perm, sign = _axis_map(up)
    return R[..., perm, :][..., perm] * np.outer(sign, sign)


def floor_height(positions: np.ndarray, percentile: float = 5.0) -> float:
    """Height of the floor a clip was captured on: a low percentile of the lowest joint of
    each frame, metres. positions: shape (T, J, 3), z up."""
    return float(np.percentile(positions[..., 2].min(axis=-1), percentile))
