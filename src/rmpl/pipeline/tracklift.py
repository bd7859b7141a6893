"""Lift whole tracks: each tracked person's 2D over time through the temporal model.

After :func:`rmpl.pipeline.tracking.track_indices` has linked the per-frame people, every
track has, for each frame, the index of its associated 2D person (or none). This stage
gathers each track's multi-view 2D into one sequence and lifts it with
:class:`rmpl.inference_temporal.TemporalLifter`. A track is cut where it is missing for more
than ``max_gap`` frames: each piece is lifted on its own, and the frames between pieces stay
empty, as the gap filler of :func:`rmpl.pipeline.runner.smooth` leaves them.

Shape glossary: ``T`` frames, ``P`` tracks, ``V`` views, ``J`` joints.
"""

from __future__ import annotations

import numpy as np

from rmpl.geometry.camera import Rig

__all__ = ["lift_tracks", "pieces", "tracks_2d"]


def tracks_2d(people, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each track's 2D per frame.

    Args:
        people: per frame, an object with ``keypoints`` (N, V, J, 2) and ``scores`` (N, V, J)
            (an :class:`rmpl.pipeline.association.Association`).
        index: (T, P) the person of each track in each frame, -1 where absent.

    Returns:
        keypoints (T, P, V, J, 2), NaN where absent, and scores (T, P, V, J), 0 there.
    """
    T, P = index.shape
    first = next(p for p in people if len(p))
    V, J = first.keypoints.shape[1:3]
    kp = np.full((T, P, V, J, 2), np.nan)
    sc = np.zeros((T, P, V, J))
    for t, p in zip(*np.nonzero(index >= 0), strict=True):
        kp[t, p] = people[t].keypoints[index[t, p]]
        sc[t, p] = people[t].scores[index[t, p]]
    return kp, sc


def pieces(present: np.ndarray, max_gap: int) -> list[tuple[int, int]]:
    """Frame ranges [a, b) of a track, cut where it is absent for more than ``max_gap``
    frames. present: (T,) bool.

    >>> pieces(np.array([0, 1, 1, 0, 1, 0, 0, 0, 1], bool), max_gap=2)
    [(1, 5), (8, 9)]
    """
    frames = np.flatnonzero(present)
    if not len(frames):
        return []
    cuts = np.flatnonzero(np.diff(frames) > max_gap + 1)
    starts = np.r_[frames[0], frames[cuts + 1]]
    ends = np.r_[frames[cuts] + 1, frames[-1] + 1]
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def lift_tracks(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    lifter,
    fps: float,
    max_gap: int = 20,
    up: np.ndarray | None = None,
    joints: str | None = None,
    floor=None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lift every track with a temporal lifter.

    Args:
        keypoints: (T, P, V, J_2d, 2) from :func:`tracks_2d`; scores: (T, P, V, J_2d).
        rig: the V cameras. lifter: a :class:`~rmpl.inference_temporal.TemporalLifter`.
        fps: frames per second. max_gap: the longest absence bridged, frames.
        up: world up axis (3,), or None to estimate it from the rig.
        joints: the 2D's joint set (None: the model's when J_2d matches, else COCO-17).
        floor: the floor (:class:`rmpl.geometry.floor.Floor`) for a model that reads it
            (:attr:`~rmpl.inference_temporal.TemporalLifter.reads_floor`; others ignore it),
            the same for every track; None = unknown.

    Returns:
        points (T, P, J, 3) metres, radius (T, P, J) metres (the predicted 50% error radius,
        :meth:`~rmpl.inference_temporal.TrackResult.radius`), views (T, P, J) int (the views
        with the joint's keypoint; 0 for a joint the 2D lacks); NaN / 0 outside each track's
        pieces. J and its order are the model's (:attr:`lifter.skeleton
        <rmpl.inference_temporal.TemporalLifter.skeleton>`).
    """
    from rmpl.skeleton import to_model_joints

    T, P = keypoints.shape[:2]
    J = lifter.num_joints
    points = np.full((T, P, J, 3), np.nan)
    radius = np.full((T, P, J), np.nan)
    present = (scores > 0).any((2, 3))  # (T, P)
    for p in range(P):
        for a, b in pieces(present[:, p], max_gap):
            r = lifter.lift_track(
                keypoints[a:b, p], scores[a:b, p], rig, fps=fps, up=up, joints=joints, floor=floor
            )
            points[a:b, p], radius[a:b, p] = r.points, r.radius(0.5)
    if keypoints.shape[-2] != J or joints not in (None, lifter.skeleton.name):
        scores = to_model_joints(keypoints, scores, lifter.skeleton, joints)[1]
    views = (scores > 0).sum(2)
    return points, radius, views
