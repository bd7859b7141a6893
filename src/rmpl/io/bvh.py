"""BVH export: a COCO-17 skeleton with constant bone lengths fitted to 3D poses.

BVH stores a fixed skeleton (bone offsets) and per-frame joint rotations, so free 3D points
have to be turned into one. :func:`fit_skeleton` does it for one person:

- Bone lengths are the medians over the sequence; the rest pose is a T-pose facing -y with
  its left side at +x and z up (the world of rmpl; ``up_axis="y"`` turns it Y-up).
- The hierarchy is ``pelvis`` (root, the mid-hip, 6 channels) with ``left_hip`` /
  ``right_hip`` -> knee -> ankle, and ``spine`` (at the pelvis) -> ``neck`` (mid-shoulder)
  -> ``left_shoulder`` / ``right_shoulder`` -> elbow -> wrist and ``head`` (at the neck) ->
  ``nose`` -> eyes and ears. Joints named like COCO-17 joints sit on them.
- Each joint's rotation points its bone at its child: the pelvis from the hip line and
  the spine, the neck from the shoulder line and the spine, limbs and the spine by the
  smallest rotation from the parent's frame, the head (eyes, ears) by a least-squares
  (Kabsch) fit of its rigid shape. Limb twist is not observable from joint centres and is
  left at the smallest rotation.

So every joint position is reproduced up to the change of its bone length from the median
(and, for eyes and ears, the head's deviation from a rigid shape).

Missing joints are interpolated linearly in time (held at the ends) before the fit; BVH
frames are contiguous, so frames absent from ``poses.frames`` are interpolated too. A joint
never seen gets a default length and its parent's rotation.

Channels: root ``Xposition Yposition Zposition Zrotation Xrotation Yrotation``, other joints
``Zrotation Xrotation Yrotation`` in degrees, i.e. the local rotation is
``Rz(a) @ Rx(b) @ Ry(c)`` and a joint's world rotation is its parent's times its own.

Shape glossary: ``T`` frames, ``J`` COCO joints (17), ``N`` BVH joints (21).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rmpl.errors import InputError

__all__ = ["BVH_JOINTS", "BvhSkeleton", "fit_skeleton", "forward_kinematics", "bvh_text"]

# name, parent, COCO joints whose mean is the joint's position.
_TABLE: tuple[tuple[str, int, tuple[int, ...]], ...] = (
    ("pelvis", -1, (11, 12)),  # 0
    ("left_hip", 0, (11,)),  # 1
    ("left_knee", 1, (13,)),  # 2
    ("left_ankle", 2, (15,)),  # 3
    ("right_hip", 0, (12,)),  # 4
    ("right_knee", 4, (14,)),  # 5
    ("right_ankle", 5, (16,)),  # 6
    ("spine", 0, (11, 12)),  # 7
    ("neck", 7, (5, 6)),  # 8
    ("left_shoulder", 8, (5,)),  # 9
    ("left_elbow", 9, (7,)),  # 10
    ("left_wrist", 10, (9,)),  # 11
    ("right_shoulder", 8, (6,)),  # 12
    ("right_elbow", 12, (8,)),  # 13
    ("right_wrist", 13, (10,)),  # 14
    ("head", 8, (5, 6)),  # 15
    ("nose", 15, (0,)),  # 16
    ("left_eye", 16, (1,)),  # 17
    ("right_eye", 16, (2,)),  # 18
    ("left_ear", 16, (3,)),  # 19
    ("right_ear", 16, (4,)),  # 20
)
#: BVH joint names, in file order.
BVH_JOINTS: tuple[str, ...] = tuple(n for n, _, _ in _TABLE)
_PARENTS = np.array([p for _, p, _ in _TABLE])
# Rest directions (T-pose, facing -y, left +x, z up) of joints with a fixed direction.
_X, _Z = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
_REST_DIR = {1: _X, 2: -_Z, 3: -_Z, 4: -_X, 5: -_Z, 6: -_Z, 8: _Z}
_REST_DIR |= {9: _X, 10: _X, 11: _X, 12: -_X, 13: -_X, 14: -_X}
_ZERO_OFFSET = (7, 15)  # spine and head sit on their parents
_AIM = {1: 2, 2: 3, 4: 5, 5: 6, 7: 8, 9: 10, 10: 11, 12: 13, 13: 14, 15: 16}  # joint: child
_HEAD = (17, 18, 19, 20)
_DEFAULT_LENGTH = 0.1  # metres, for a bone never seen
_END_LENGTH = 0.05  # metres: End Site after each leaf


@dataclass(frozen=True)
class BvhSkeleton:
    """A fitted skeleton and its motion.

    Attributes:
        offsets: rest offset of each joint from its parent, shape (N, 3), metres.
        root_positions: pelvis positions, shape (T, 3), metres.
        rotations: world rotation of each joint, shape (T, N, 3, 3).
        end_sites: End Site offset of each leaf joint, {joint index: (3,)}, metres.
    """

    offsets: np.ndarray
    root_positions: np.ndarray
    rotations: np.ndarray
    end_sites: dict[int, np.ndarray]

    @property
    def local_rotations(self) -> np.ndarray:
        """Rotation of each joint relative to its parent (the root's is its world one),
        shape (T, N, 3, 3)."""
        G = self.rotations
        parent = np.where(_PARENTS < 0, 0, _PARENTS)
        local = np.swapaxes(G[:, parent], -1, -2) @ G
        local[:, _PARENTS < 0] = G[:, _PARENTS < 0]
        return local


def forward_kinematics(
    offsets: np.ndarray, root_positions: np.ndarray, local_rotations: np.ndarray
) -> np.ndarray:
    """Joint positions of the rmpl BVH hierarchy, shape (T, N, 3), metres.

    Args:
        offsets: (N, 3). root_positions: (T, 3). local_rotations: (T, N, 3, 3).
    """
    T, N = local_rotations.shape[:2]
    pos = np.zeros((T, N, 3))
    G = np.zeros((T, N, 3, 3))
    for j in range(N):  # parents come first
        p = _PARENTS[j]
        if p < 0:
            pos[:, j], G[:, j] = root_positions + offsets[j], local_rotations[:, j]
        else:
            pos[:, j] = pos[:, p] + G[:, p] @ offsets[j]
            G[:, j] = G[:, p] @ local_rotations[:, j]
    return pos


def _fill_gaps(points: np.ndarray) -> np.ndarray:
    """Linear interpolation of NaN frames per joint, held at the ends; (T, J, 3)."""
    out = points.copy()
    t = np.arange(len(points))
    for j in range(points.shape[1]):
        ok = ~np.isnan(points[:, j]).any(-1)
        if ok.any() and not ok.all():
            for c in range(3):
                out[:, j, c] = np.interp(t, t[ok], points[ok, j, c])
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 1e-9, v / n, np.nan)


def _frame(x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Rotations whose x axis is along ``x`` and z axis in the (x, z) plane, (T, 3, 3)."""
    x = _unit(x)
    z = _unit(z - np.sum(z * x, -1, keepdims=True) * x)
    return np.stack([x, np.cross(z, x), z], axis=-1)


def _smallest_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotations taking unit vectors a to b, (T, 3, 3); identity where b is NaN."""
    T = len(a)
    out = np.broadcast_to(np.eye(3), (T, 3, 3)).copy()
    ok = ~np.isnan(b).any(-1) & ~np.isnan(a).any(-1)
    a, b = a[ok], b[ok]
    v = np.cross(a, b)
    c = np.sum(a * b, -1)
    s = np.linalg.norm(v, axis=-1)
    # Opposite vectors: half a turn about any axis perpendicular to a.
    flip = c < -1 + 1e-9
    perp = np.cross(a, np.where(np.abs(a[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    axis = np.where(flip[:, None], _unit(perp), v / np.where(s > 1e-12, s, 1.0)[:, None])
    angle = np.where(flip, np.pi, np.arctan2(s, c))
    Kx = np.zeros((len(a), 3, 3))
    Kx[:, 0, 1], Kx[:, 0, 2], Kx[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    Kx = Kx - np.swapaxes(Kx, 1, 2)
    sa, ca = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    out[ok] = np.eye(3) + sa * Kx + (1 - ca) * Kx @ Kx
    return out


def _kabsch(rest: np.ndarray, target: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Rotations R (T, 3, 3) minimising sum |R rest_c - target_c|^2 over valid c.

    rest: (C, 3). target: (T, C, 3), NaN = not used. Frames with fewer than 2 valid
    points keep ``fallback``.
    """
    ok = ~np.isnan(target).any(-1)  # (T, C)
    tgt = np.where(ok[..., None], target, 0.0)
    H = np.einsum("ci,tcj->tij", rest, tgt)  # (T, 3, 3)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, 1, 2) @ np.swapaxes(U, 1, 2)))
    D = np.broadcast_to(np.eye(3), H.shape).copy()
    D[:, 2, 2] = d
    R = np.swapaxes(Vt, 1, 2) @ D @ np.swapaxes(U, 1, 2)
    return np.where((ok.sum(1) >= 2)[:, None, None], R, fallback)


def _median_length(a: np.ndarray, b: np.ndarray) -> float:
    d = np.linalg.norm(b - a, axis=-1)
    d = d[np.isfinite(d)]
    return float(np.median(d)) if len(d) else _DEFAULT_LENGTH


def fit_skeleton(points: np.ndarray) -> BvhSkeleton:
    """Fit the constant-length BVH skeleton to one person's COCO-17 points.

    Args:
        points: world metres, shape (T, 17, 3), z up, NaN = missing; the hips and the
            shoulders must be seen in at least one frame.

    Returns:
        The skeleton (see :class:`BvhSkeleton`).

    Raises:
        InputError: wrong shape, or no frame with both hips and both shoulders.
    """
    X = np.asarray(points, dtype=float)
    if X.ndim != 3 or X.shape[1:] != (17, 3):
        raise InputError(None, "points", "shape (T, 17, 3) (COCO-17)", X.shape)
    if not (~np.isnan(X[:, [5, 6, 11, 12]]).any(-1)).all(-1).any():
        raise InputError(None, "points", "both hips and both shoulders in some frame", "none")
    X = _fill_gaps(X)
    T, N = len(X), len(_TABLE)
    P = np.stack([X[:, list(idx)].mean(1) for _, _, idx in _TABLE], axis=1)  # (T, N, 3)
    offsets = _rest_offsets(P)
    G = np.zeros((T, N, 3, 3))
    spine = P[:, 8] - P[:, 0]
    G[:, 0] = _frame(P[:, 1] - P[:, 4], spine)
    G[:, 8] = _frame(P[:, 9] - P[:, 12], spine)

    def aim(j: int) -> None:
        child = _AIM[j]
        rest = G[:, _PARENTS[j]] @ _unit(offsets[child])
        G[:, j] = _smallest_rotation(rest, _unit(P[:, child] - P[:, j])) @ G[:, _PARENTS[j]]

    for j in (1, 2, 4, 5, 7):
        aim(j)
    G[:, 8] = np.where(np.isnan(G[:, 8]), G[:, 7], G[:, 8])
    for j in (9, 10, 12, 13):
        aim(j)
    # The nose's rest direction: its median direction in the neck's frame.
    local = np.einsum("tji,tj->ti", G[:, 8], _unit(P[:, 16] - P[:, 8]))
    local = local[np.isfinite(local).all(-1)]
    nose_dir = _unit(np.median(local, 0)) if len(local) else _unit(np.array([0.0, -0.5, 1.0]))
    offsets[16] = nose_dir * _median_length(P[:, 8], P[:, 16])
    aim(15)
    # The head's rigid shape: eyes and ears in the head's frame, medians.
    rel = P[:, list(_HEAD)] - P[:, 16:17]  # (T, 4, 3)
    local = np.einsum("tji,tcj->tci", G[:, 15], rel)
    for k, j in enumerate(_HEAD):
        ok = np.isfinite(local[:, k]).all(-1)
        offsets[j] = np.median(local[ok, k], 0) if ok.any() else [0.0, 0.0, 0.05]
    G[:, 16] = _kabsch(offsets[list(_HEAD)], rel, G[:, 15])
    for j in (3, 6, 11, 14, *_HEAD):  # leaves keep their parent's rotation
        G[:, j] = G[:, _PARENTS[j]]
    G = np.where(np.isnan(G), np.eye(3), G)  # a joint never seen: no rotation data
    ends = {j: _END_LENGTH * _unit(offsets[j]) for j in (3, 6, 11, 14, *_HEAD)}
    return BvhSkeleton(offsets, P[:, 0], G, ends)


def _rest_offsets(P: np.ndarray) -> np.ndarray:
    """Each joint's rest offset from its parent (N, 3): its rest direction times the bone's
    median length (each half of the hip and shoulder lines: half the line's)."""
    offsets = np.zeros((len(_TABLE), 3))
    for j, d in _REST_DIR.items():
        length = _median_length(P[:, _PARENTS[j]], P[:, j])
        if j in (1, 4, 9, 12):  # each half of the hip or shoulder line
            length = _median_length(P[:, 1 if j in (1, 4) else 9], P[:, 4 if j in (1, 4) else 12])
            length /= 2
        offsets[j] = d * length
    return offsets


def _euler_zxy(R: np.ndarray) -> np.ndarray:
    """(*, 3, 3) -> degrees (z, x, y) with R = Rz @ Rx @ Ry."""
    from scipy.spatial.transform import Rotation

    shape = R.shape[:-2]
    angles = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_euler("ZXY", degrees=True)
    return angles.reshape(*shape, 3)


def bvh_text(
    points: np.ndarray, fps: float, scale: float = 1.0, axes: np.ndarray | None = None
) -> str:
    """The BVH file of one person.

    Args:
        points: world metres, shape (T, 17, 3), z up, contiguous frames, NaN = missing.
        fps: frames per second.
        scale: file units per metre (1 for metres, 1000 for millimetres).
        axes: rotation (3, 3) from the world to the file's axes (None: unchanged).

    Returns:
        The file's text.
    """
    fit = fit_skeleton(points)
    A = np.eye(3) if axes is None else np.asarray(axes, float)
    offsets = fit.offsets @ A.T * scale
    root = fit.root_positions @ A.T * scale
    local = A @ fit.local_rotations @ A.T  # the same motion in the file's axes
    angles = _euler_zxy(local)  # (T, N, 3)
    children = {j: [k for k in range(len(_TABLE)) if _PARENTS[k] == j] for j in range(len(_TABLE))}
    lines = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        pad = "\t" * depth
        kind = "ROOT" if _PARENTS[j] < 0 else "JOINT"
        lines.append(f"{pad}{kind} {BVH_JOINTS[j]}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}\tOFFSET " + " ".join(f"{x:.6f}" for x in offsets[j]))
        pos = "Xposition Yposition Zposition " if _PARENTS[j] < 0 else ""
        count = 6 if pos else 3
        lines.append(f"{pad}\tCHANNELS {count} {pos}Zrotation Xrotation Yrotation")
        for k in children[j]:
            emit(k, depth + 1)
        if j in fit.end_sites:
            end = A @ fit.end_sites[j] * scale
            lines.append(f"{pad}\tEnd Site")
            lines.append(f"{pad}\t{{")
            lines.append(f"{pad}\t\tOFFSET " + " ".join(f"{x:.6f}" for x in end))
            lines.append(f"{pad}\t}}")
        lines.append(f"{pad}}}")

    emit(0, 0)
    lines += ["MOTION", f"Frames: {len(root)}", f"Frame Time: {1.0 / fps:.8f}"]
    values = np.concatenate([root, angles.reshape(len(root), -1)], axis=1)
    lines += [" ".join(f"{x:.6f}" for x in row) for row in values]
    return "\n".join(lines) + "\n"
