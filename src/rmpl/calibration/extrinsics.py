"""Where the cameras are, before the bundle adjustment: a spanning tree over shared views.

Each camera's view of the board gives the board's pose in that camera (``cv2.solvePnP``).
Two cameras that saw the board at the same instant give one estimate of their relative
pose; over all their shared instants the estimate most others agree with (within 5
degrees and 10% of the distance) is kept and averaged with those that agree. Cameras are
then chained from the camera with the most links along the maximum spanning tree of the
graph whose edges weigh the agreeing shared views. A checkerboard looks the same turned
180 degrees, so OpenCV may number its corners from either end: both readings of a view are
tried and the one that agrees is kept (``flip``).

Poses are 4x4 matrices mapping points of the first frame into the second: ``T_cb`` board
-> camera, ``T_cw`` world -> camera (the world here is the reference camera's frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rmpl.calibration.boards import Board
from rmpl.calibration.detect import Detection
from rmpl.errors import InputError

__all__ = ["Chain", "board_flip", "chain_cameras", "solve_board_poses", "to_matrix"]


def _cv2():
    import cv2

    return cv2


def to_matrix(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.ravel(t)
    return T


def inverse(T: np.ndarray) -> np.ndarray:
    R, t = T[:3, :3], T[:3, 3]
    return to_matrix(R.T, -R.T @ t)


def board_flip(board: Board) -> np.ndarray:
    """Board point -> the point with the reversed corner number (turned 180 degrees)."""
    far = board.points[-1]
    return to_matrix(np.diag([-1.0, -1.0, 1.0]), [far[0], far[1], 0.0])


def solve_board_poses(
    views: dict[int, Detection], K: np.ndarray, dist: np.ndarray, board: Board
) -> dict[int, np.ndarray]:
    """Board -> camera pose of each view, 4x4 (IPPE for planar targets, then refined)."""
    cv2 = _cv2()
    out = {}
    for k, det in views.items():
        obj = board.points[det.ids].astype(np.float64)
        img = det.corners.astype(np.float64)
        ok, rv, tv = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
        if not ok:
            continue
        rv, tv = cv2.solvePnPRefineLM(obj, img, K, dist, rv, tv)
        R = cv2.Rodrigues(rv)[0]
        if tv[2, 0] > 0:
            out[k] = to_matrix(R, tv)
    return out


def _angle(Ra: np.ndarray, Rb: np.ndarray) -> float:
    c = (np.trace(Ra.T @ Rb) - 1) / 2
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _mean_pose(Ts: list[np.ndarray]) -> np.ndarray:
    """Chordal mean of the rotations (SVD of their sum), mean of the translations."""
    U, _, Vt = np.linalg.svd(sum(T[:3, :3] for T in Ts))
    R = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    return to_matrix(R, np.mean([T[:3, 3] for T in Ts], axis=0))


def _agree(A: np.ndarray, B: np.ndarray) -> bool:
    dist = max(np.linalg.norm(A[:3, 3]), 1e-6)
    return _angle(A[:3, :3], B[:3, :3]) < 5.0 and np.linalg.norm(A[:3, 3] - B[:3, 3]) < 0.1 * dist


def _relative(pa: dict, pb: dict, flips: list[np.ndarray]) -> tuple[np.ndarray | None, int]:
    """Camera b -> camera a from their shared views: the consensus estimate and its support."""
    cands = [pa[f] @ inverse(pb[f] @ F) for f in sorted(set(pa) & set(pb)) for F in flips]
    if not cands:
        return None, 0
    support = [[c for c in cands if _agree(c, d)] for d in cands]
    best = max(range(len(cands)), key=lambda i: len(support[i]))
    return _mean_pose(support[best]), len(support[best])


@dataclass
class Chain:
    """Cameras placed by the tree. T_cw[v]: world -> camera v (4x4); flips[v][f]: view f of
    camera v read turned 180 degrees; T_wb[f]: board -> world at instant f."""

    T_cw: list[np.ndarray]
    flips: list[dict[int, bool]]
    T_wb: dict[int, np.ndarray]
    reference: int
    edges: list[tuple[int, int, int]]


def chain_cameras(poses: list[dict[int, np.ndarray]], names: list[str], board: Board) -> Chain:
    """Place every camera from the board views they share (see the module).

    Raises:
        InputError: "could not build the calibration graph": a camera shares no board view
            with the others (named, with the cameras it could not be linked to).
    """
    V = len(poses)
    flips = [np.eye(4)] + ([board_flip(board)] if board.kind == "checkerboard" else [])
    rel: dict[tuple[int, int], tuple[np.ndarray, int]] = {}
    for a in range(V):
        for b in range(a + 1, V):
            T, n = _relative(poses[a], poses[b], flips)
            if T is not None:
                rel[a, b], rel[b, a] = (T, n), (inverse(T), n)
    degree = [sum(n for (a, _), (_, n) in rel.items() if a == v) for v in range(V)]
    root = int(np.argmax(degree))
    placed, T_cw, edges = {root}, {root: np.eye(4)}, []
    while len(placed) < V:
        best = max(
            ((rel[a, b][1], a, b) for (a, b) in rel if a in placed and b not in placed),
            default=None,
        )
        if best is None:
            lonely = [names[v] for v in range(V) if v not in placed]
            raise InputError(
                None, "extrinsics", "every camera to share board views with another "
                "(film the board where two cameras see it at once)",
                f"could not build the calibration graph: {', '.join(lonely)} shares no "
                f"view with {', '.join(names[v] for v in sorted(placed))}",
            )  # fmt: skip
        n, a, b = best
        T_cw[b] = inverse(rel[a, b][0]) @ T_cw[a]  # world -> a -> b
        placed.add(b)
        edges.append((a, b, n))
    T_cw_list = [T_cw[v] for v in range(V)]
    T_wb, flip = _board_poses(poses, T_cw_list, flips)
    return Chain(T_cw_list, flip, T_wb, root, edges)


def _board_poses(poses, T_cw, flips):
    """Each instant's board pose in the world from the camera that saw it first, and each
    other view's reading (plain or turned) that agrees best with it."""
    T_wb: dict[int, np.ndarray] = {}
    flip: list[dict[int, bool]] = [{} for _ in poses]
    for v, pv in enumerate(poses):
        for f, T in pv.items():
            in_world = [inverse(T_cw[v]) @ T @ F for F in flips]
            if f not in T_wb:
                T_wb[f], flip[v][f] = in_world[0], False
                continue
            errs = [
                _angle(W[:3, :3], T_wb[f][:3, :3]) + 100 * np.linalg.norm(W[:3, 3] - T_wb[f][:3, 3])
                for W in in_world
            ]
            flip[v][f] = bool(np.argmin(errs) == 1)
    return T_wb, flip
