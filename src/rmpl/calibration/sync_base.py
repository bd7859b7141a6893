"""People followed frame to frame in one view, and the geometry helpers that
synchronisation and calibration from people share (:mod:`rmpl.calibration.sync`,
:mod:`rmpl.calibration.sync_3d`, :mod:`rmpl.calibration.people`).

Shape glossary: ``T`` frames, ``P`` people, ``J`` joints.
"""

from __future__ import annotations

import numpy as np

__all__ = ["link_index", "link_people"]


def _sizes(kp: np.ndarray) -> np.ndarray:
    """Each person's size: the diagonal of its keypoints' box, pixels. kp (..., J, 2)."""
    with np.errstate(invalid="ignore"), _quiet():
        lo, hi = np.nanmin(kp, axis=-2), np.nanmax(kp, axis=-2)
    return np.linalg.norm(hi - lo, axis=-1)


class _quiet:
    def __enter__(self):
        import warnings

        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *exc):
        self._w.__exit__(*exc)


def link_index(keypoints: np.ndarray, max_move: float = 0.5, max_gap: int = 3) -> np.ndarray:
    """The track of each person of one view in each frame.

    People are matched between a frame and the last frames seen (up to ``max_gap`` back)
    by the Hungarian method on the mean distance of their common joints, in units of the
    person's size; a match further than ``max_move`` starts a new track.

    Args:
        keypoints: one view, shape (T, P, J, 2), pixels; NaN = missing. Person ``p`` need
            not be the same person in two frames.

    Returns:
        Shape (T, P), int: the track of each person, -1 where nobody is.
    """
    from scipy.optimize import linear_sum_assignment

    kp = np.asarray(keypoints, float)
    T, P = kp.shape[:2]
    present = np.isfinite(kp).all(-1).sum(-1) >= 3  # (T, P)
    last: list[tuple[int, np.ndarray]] = []  # per track: (frame, keypoints)
    rows = np.full((T, P), -1)
    for t in range(T):
        people = np.flatnonzero(present[t])
        assign = {}
        alive = [q for q, (f, _) in enumerate(last) if t - f <= max_gap]
        if len(people) and alive:
            prev = np.stack([last[q][1] for q in alive])  # (A, J, 2)
            d = np.linalg.norm(kp[t, people][:, None] - prev[None], axis=-1)  # (N, A, J)
            with _quiet():
                cost = np.nanmean(d, -1) / np.maximum(_sizes(prev)[None], 1.0)
            cost = np.where(np.isfinite(cost), cost, 1e6)
            for i, a in zip(*linear_sum_assignment(cost), strict=True):
                if cost[i, a] <= max_move:
                    assign[int(people[i])] = alive[a]
        for p in people:
            q = assign.get(int(p))
            if q is None:
                q = len(last)
                last.append((t, kp[t, p]))
            last[q] = (t, np.where(np.isfinite(kp[t, p]), kp[t, p], last[q][1]))
            rows[t, p] = q
    return rows


def link_people(keypoints: np.ndarray, *values: np.ndarray) -> np.ndarray | tuple:
    """One view's people laid out by track (:func:`link_index`): person ``q`` of the
    result is one person throughout.

    Args:
        keypoints: shape (T, P, J, 2), pixels; NaN = missing.
        values: other per-person arrays (T, P, ...) to lay out the same way (scores).

    Returns:
        Tracks, shape (T, Q, J, 2), NaN where a track is absent; with ``values``, a tuple
        of the tracks and each value laid out alike (NaN where absent).
    """
    kp = np.asarray(keypoints, float)
    rows = link_index(kp)
    Q = max(int(rows.max()) + 1, 1)
    out = []
    for a in (kp, *values):
        a = np.asarray(a, float)
        lay = np.full((a.shape[0], Q) + a.shape[2:], np.nan)
        t, p = np.nonzero(rows >= 0)
        lay[t, rows[t, p]] = a[t, p]
        out.append(lay)
    return tuple(out) if values else out[0]


def _normalised(points: np.ndarray, cam) -> np.ndarray:
    from rmpl.geometry.camera import undistort

    K = cam.K
    v = (points[..., 1] - K[1, 2]) / K[1, 1]
    u = (points[..., 0] - K[0, 2] - K[0, 1] * v) / K[0, 0]
    return undistort(np.stack([u, v], -1), cam.dist)


def _essential(rig, a: int, b: int) -> np.ndarray:
    """E with x_b^T E x_a = 0 for normalised points of cameras a and b."""
    Ra, ta, Rb, tb = rig[a].R, rig[a].t, rig[b].R, rig[b].t
    R = Rb @ Ra.T
    t = tb - R @ ta
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return tx @ R


# --------------------------------------------------------------------------- the whole
