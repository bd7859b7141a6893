"""Identities over time: link the 3D people of successive frames into tracks.

Each frame's people come unordered (from :func:`rmpl.pipeline.association.associate` or any other
source). A track predicts where its person will be with a constant-velocity model; the
predictions and the new people are matched by the Hungarian algorithm on the mean
distance between their joints, and a match farther than ``max_distance`` is refused
(gating). A person left unmatched starts a new track; a track unmatched for more than
``max_missed`` frames in a row ends and is never resumed here: joining such fragments
(a person who leaves and returns, one person tracked twice) is
:func:`rmpl.pipeline.identity.resolve`'s work, which ``rmpl run`` applies next.

Shape glossary: ``T`` frames, ``N`` people of one frame, ``P`` tracks, ``J`` joints.
Metres; a missing joint is NaN.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rmpl.errors import InputError

__all__ = ["track", "track_indices"]

_REFUSED = 1e9  # cost of a gated pair in the assignment


@dataclass
class _Track:
    """One person's state: last position of every joint and a whole-body velocity."""

    position: np.ndarray  # (J, 3), NaN for joints never seen
    last_frame: int
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # metres per frame
    detections: dict[int, int] = field(default_factory=dict)  # frame -> index in that frame

    def predict(self, frame: int) -> np.ndarray:
        return self.position + self.velocity * (frame - self.last_frame)

    def update(self, points: np.ndarray, frame: int, index: int) -> None:
        seen = ~np.isnan(points[:, 0])
        both = seen & ~np.isnan(self.position[:, 0])
        dt = frame - self.last_frame
        if both.any():
            self.velocity = (points[both] - self.position[both]).mean(0) / dt
        moved = self.predict(frame)  # joints not seen now move with the body
        self.position = np.where(seen[:, None], points, moved)
        self.last_frame = frame
        self.detections[frame] = index


def _check_frames(poses_per_frame) -> list[np.ndarray]:
    if isinstance(poses_per_frame, np.ndarray) and poses_per_frame.ndim == 4:
        poses_per_frame = list(poses_per_frame)  # (T, N, J, 3): N slots per frame
    if not isinstance(poses_per_frame, Sequence) or len(poses_per_frame) == 0:
        raise InputError(
            None,
            "poses_per_frame",
            "a non-empty list of (N, J, 3) arrays",
            type(poses_per_frame).__name__,
        )
    frames, joints = [], None
    for t, people in enumerate(poses_per_frame):
        field_name = f"poses_per_frame[{t}]"
        try:
            x = np.asarray(people, dtype=float)
        except (TypeError, ValueError):
            raise InputError(
                None, field_name, "an (N, J, 3) array", type(people).__name__
            ) from None
        if x.ndim != 3 or x.shape[-1] != 3 or (joints is not None and x.shape[1] != joints):
            want = f"(N, {joints if joints is not None else 'J'}, 3)"
            raise InputError(None, field_name, f"shape {want}, the same J in every frame", x.shape)
        if np.isinf(x).any():
            raise InputError(None, field_name, "finite coordinates or NaN for missing", "inf")
        joints = x.shape[1]
        frames.append(x)
    return frames


def _cost(predicted: np.ndarray, people: np.ndarray) -> np.ndarray:
    """Mean joint distance over the joints both have, shape (P, N); inf when none."""
    d = np.linalg.norm(predicted[:, None] - people[None], axis=-1)  # (P, N, J), NaN if absent
    common = ~np.isnan(d)
    total = np.where(common, d, 0.0).sum(-1)
    count = common.sum(-1)
    return np.where(count > 0, total / np.maximum(count, 1), np.inf)


def _match(cost: np.ndarray, max_distance: float) -> list[tuple[int, int]]:
    from scipy.optimize import linear_sum_assignment

    if cost.size == 0:
        return []
    rows, cols = linear_sum_assignment(np.where(cost <= max_distance, cost, _REFUSED))
    return [
        (r, c)
        for r, c in zip(rows.tolist(), cols.tolist(), strict=True)
        if cost[r, c] <= max_distance
    ]


def track_indices(
    poses_per_frame: Sequence[np.ndarray] | np.ndarray,
    max_distance: float = 0.5,
    max_missed: int = 10,
    min_length: int = 1,
) -> np.ndarray:
    """Which person of each frame belongs to which track.

    Args:
        poses_per_frame: per frame, the people seen, shape (N_t, J, 3) metres, NaN for a
            missing joint (N_t may be 0). A (T, N, J, 3) array works too. People with no
            joint at all are ignored.
        max_distance: largest mean joint distance, in metres, between a track's predicted
            pose and a person for them to be matched (the gate).
        max_missed: frames in a row a track may go unmatched before it ends.
        min_length: tracks seen in fewer frames are dropped (1 keeps every track).

    Returns:
        Index of the person in each frame's array, shape (T, P), -1 where the track is
        absent; tracks are ordered by their first frame (then by index in that frame).

    >>> a = np.zeros((1, 2, 3)); b = a + [2.0, 0.0, 0.0]
    >>> track_indices([np.concatenate([a, b]), np.concatenate([b, a])]).tolist()
    [[0, 1], [1, 0]]
    """
    frames = _check_frames(poses_per_frame)
    max_distance = float(max_distance)
    if not np.isfinite(max_distance) or max_distance <= 0:
        raise InputError(None, "max_distance", "a positive distance in metres", max_distance)
    for name, value, low in (("max_missed", max_missed, 0), ("min_length", min_length, 1)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
            raise InputError(None, name, f"an integer >= {low}", value)

    active: list[_Track] = []
    done: list[_Track] = []
    for t, people in enumerate(frames):
        real = np.flatnonzero(~np.isnan(people[..., 0]).all(-1))  # people with any joint
        if active:
            predicted = np.stack([tr.predict(t) for tr in active])  # (P, J, 3)
            matches = _match(_cost(predicted, people[real]), max_distance)
        else:
            matches = []
        for r, c in matches:
            active[r].update(people[real[c]], t, int(real[c]))
        taken = {c for _, c in matches}
        new = [
            _Track(people[i].copy(), t, detections={t: int(i)})
            for k, i in enumerate(real.tolist())
            if k not in taken
        ]
        still = [tr for tr in active if t - tr.last_frame <= max_missed]
        done += [tr for tr in active if t - tr.last_frame > max_missed]
        active = still + new

    tracks = [tr for tr in done + active if len(tr.detections) >= min_length]
    tracks.sort(key=lambda tr: min(tr.detections.items()))
    index = np.full((len(frames), len(tracks)), -1, dtype=np.int64)
    for p, tr in enumerate(tracks):
        for t, i in tr.detections.items():
            index[t, p] = i
    return index


def track(
    poses_per_frame: Sequence[np.ndarray] | np.ndarray,
    max_distance: float = 0.5,
    max_missed: int = 10,
    min_length: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Link the 3D people of successive frames into identities.

    Args:
        poses_per_frame: per frame, the people seen, shape (N_t, J, 3) metres; see
            :func:`track_indices`, which also gives the settings.
        max_distance: gate on the mean joint distance to the prediction, metres.
        max_missed: frames in a row a track may go unmatched before it ends.
        min_length: tracks seen in fewer frames are dropped.

    Returns:
        ``(tracks, ids)``: poses per track, shape (T, P, J, 3), NaN where the track is
        absent; and track ids, shape (P,), 0..P-1 in order of first appearance (to use as
        :attr:`rmpl.io.poses.Poses3D.person_ids`). Use :func:`track_indices` to carry
        scores or flags along.

    >>> walker = np.zeros((1, 2, 3))
    >>> tracks, ids = track([walker + [0.05 * t, 0.0, 0.0] for t in range(5)])
    >>> tracks.shape, ids.tolist()
    ((5, 1, 2, 3), [0])
    """
    frames = _check_frames(poses_per_frame)
    index = track_indices(frames, max_distance, max_missed, min_length)
    T, P = index.shape
    J = frames[0].shape[1]
    tracks = np.full((T, P, J, 3), np.nan)
    for t, people in enumerate(frames):
        present = index[t] >= 0
        tracks[t, present] = people[index[t, present]]
    return tracks, np.arange(P, dtype=np.int64)
