"""Ablation (not shipped): joints one view sees, placed on that view's ray at the bone length
the track shows where two views agree, against the temporal model's own answer.

Usage: python scripts/temporal_bonefit.py SEQBANK [MODEL] [--windows 64] [--views 2,3]

On held-out synthetic windows (CMU subject 03, the temporal detector model, seed 777) it
prints, over the joints the placement moves, the temporal model's error and the placed
joints' error: with parents and bone lengths measured from the 2D (what a user would get),
and with the true parents and lengths (an upper bound on the idea).

The method:

Over a track the person's bones keep their length. Where two or more views see both ends of
a bone and their rays meet, the bone is measured; its length over the track is the median
of those measurements. In a frame where a joint is seen by exactly one view, it lies on that
view's ray; when its parent joint is known in that frame, it also lies on the sphere around
the parent with the bone's radius. The ray meets the sphere in at most two points: the one
nearer a prior guess (the temporal model's answer) is taken. A ray that misses the sphere
gives its point nearest the parent. Parents are placed before children, from the torso
outward, so an elbow placed this way anchors its wrist.

Only the twelve limb and torso joints of COCO-17 (shoulders, elbows, wrists, hips, knees,
ankles) are placed; the face's bones are a few centimetres long, shorter than a single view's
depth error, and keep the prior.

All functions work on one track in world metres. Shape glossary: ``T`` frames, ``V`` views,
``J`` joints.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

#: COCO-17 joint -> candidate parents in order of preference (torso before limbs).
PARENTS: dict[int, tuple[int, ...]] = {
    5: (6, 11),  # left shoulder: right shoulder, left hip
    6: (5, 12),
    11: (12, 5),  # left hip: right hip, left shoulder
    12: (11, 6),
    7: (5,),  # left elbow: left shoulder
    8: (6,),
    9: (7,),  # left wrist: left elbow
    10: (8,),
    13: (11,),  # left knee: left hip
    14: (12,),
    15: (13,),  # left ankle: left knee
    16: (14,),
}
#: The order joints are placed in: each joint's parents come earlier.
ORDER: tuple[int, ...] = (5, 6, 11, 12, 7, 8, 13, 14, 9, 10, 15, 16)


@dataclass(frozen=True)
class BoneFitConfig:
    """Settings of :func:`fit_single_view`.

    Attributes:
        max_ray_distance: two or more rays "agree" on a joint when each passes within this
            distance (metres) of their least-squares intersection.
        min_frames: a bone is measured from at least this many frames where both its ends
            agree; otherwise its length is the median over the prior's frames.
        max_miss: a ray that misses the sphere by more than this (metres) does not place
            the joint (the 2D or the parent is wrong): the prior stays.
    """

    max_ray_distance: float = 0.05
    min_frames: int = 5
    max_miss: float = 0.10

    def __post_init__(self) -> None:
        for name in ("max_ray_distance", "max_miss"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0 metres, got {value}")
        if self.min_frames < 1:
            raise ValueError(f"min_frames must be >= 1, got {self.min_frames}")


def intersect_rays(rays: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares meeting point of each joint's rays.

    Args:
        rays: (..., V, J, 6) origin and unit direction, world metres.
        weights: (..., V, J) >= 0; 0 drops a view.

    Returns:
        points (..., J, 3), NaN where fewer than two views have weight, and the largest
        distance (..., J) from a weighted ray to its point (metres).

    >>> o = np.array([[0.0, 0, 0], [2.0, 0, 0]])
    >>> d = np.array([[1.0, 1, 0], [-1.0, 1, 0]]) / np.sqrt(2)
    >>> X, dist = intersect_rays(np.concatenate([o, d], -1)[:, None], np.ones((2, 1)))
    >>> np.round(X, 6).tolist(), float(np.round(dist[0], 6))
    ([[1.0, 1.0, 0.0]], 0.0)
    """
    o, d = rays[..., :3], rays[..., 3:]
    w = np.where(np.isfinite(weights), weights, 0.0)
    proj = np.eye(3) - d[..., :, None] * d[..., None, :]  # (..., V, J, 3, 3)
    A = (w[..., None, None] * proj).sum(-4)
    b = (w[..., None, None] * proj @ o[..., None]).sum(-4)[..., 0]
    enough = (w > 0).sum(-2) >= 2
    A = np.where(enough[..., None, None], A, np.eye(3))
    with np.errstate(invalid="ignore"):
        X = np.linalg.solve(A, b[..., None])[..., 0]
    X[~enough] = np.nan
    off = X[..., None, :, :] - o  # (..., V, J, 3)
    along = (off * d).sum(-1, keepdims=True)
    dist = np.linalg.norm(off - along * d, axis=-1)
    dist = np.where(w > 0, dist, 0.0).max(-2)
    return X, np.where(enough, dist, np.nan)


def bone_lengths(
    anchors: np.ndarray, prior: np.ndarray, min_frames: int
) -> dict[tuple[int, int], float]:
    """Each (parent, child) bone of :data:`PARENTS`: its median length over the frames where
    both ends are anchored (agreeing views), or over the prior's frames when fewer than
    ``min_frames`` are. anchors, prior: (T, J, 3), NaN = unknown."""
    out = {}
    for child, parents in PARENTS.items():
        for parent in parents:
            m = np.linalg.norm(anchors[:, child] - anchors[:, parent], axis=-1)
            m = m[np.isfinite(m)]
            if len(m) < min_frames:
                m = np.linalg.norm(prior[:, child] - prior[:, parent], axis=-1)
                m = m[np.isfinite(m)]
            out[(parent, child)] = float(np.median(m)) if len(m) else np.nan
    return out


def _on_sphere(o, d, centre, radius, guess, max_miss):
    """Points (N, 3) where rays (o, d) meet spheres (centre, radius), the root nearer
    ``guess``; NaN where a ray misses by more than ``max_miss``."""
    oc = o - centre
    bq = (d * oc).sum(-1)
    disc = bq**2 - ((oc * oc).sum(-1) - radius**2)
    root = np.sqrt(np.maximum(disc, 0.0))
    s1, s2 = -bq - root, -bq + root
    p1, p2 = o + s1[:, None] * d, o + s2[:, None] * d
    g = np.where(np.isfinite(guess), guess, centre)
    pick2 = (np.linalg.norm(p2 - g, axis=-1) < np.linalg.norm(p1 - g, axis=-1)) | (s1 <= 0)
    s = np.where(pick2, s2, s1)
    # A miss: the ray's point nearest the centre, if the gap is small.
    miss = disc < 0
    closest = np.linalg.norm(oc - bq[:, None] * d, axis=-1)  # distance ray-centre
    s = np.where(miss, -bq, s)
    X = o + s[:, None] * d
    bad = (miss & (closest - radius > max_miss)) | (s <= 0) | ~np.isfinite(radius)
    X[bad] = np.nan
    return X


def fit_single_view(
    rays: np.ndarray,
    scores: np.ndarray,
    prior: np.ndarray,
    config: BoneFitConfig | None = None,
    truth: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Place the limb joints seen by exactly one view on their ray at the track's bone length.

    Args:
        rays: (T, V, J, 6) world origin + unit direction per keypoint (COCO-17).
        scores: (T, V, J), 0 = not seen.
        prior: (T, J, 3) the track's current answer (e.g. the temporal model's), metres.
        config: thresholds.
        truth: (T, J, 3) true joints: parents and bone lengths from them (the upper bound).

    Returns:
        points (T, J, 3): ``prior`` with the placed joints replaced, and placed (T, J) bool.
    """
    cfg = config or BoneFitConfig()
    T, V, J = scores.shape
    seen = scores > 0
    X, dist = intersect_rays(rays, np.where(seen, scores, 0.0))
    agree = np.isfinite(X).all(-1) & (dist <= cfg.max_ray_distance)
    anchors = np.where(agree[..., None], X, np.nan)
    lengths = bone_lengths(anchors, prior, cfg.min_frames)
    known = agree.copy()
    best = np.where(agree[..., None], X, prior)  # the parents' positions
    if truth is not None:
        lengths, best = bone_lengths(truth, truth, 1), truth.copy()
    out = prior.copy()
    placed = np.zeros((T, J), bool)
    single = seen.sum(1) == 1  # (T, J)
    view = seen.argmax(1)  # the one view, where single
    t_all = np.arange(T)
    for child in ORDER:
        todo = single[:, child] & ~known[:, child]
        for parent in PARENTS[child]:
            rows = np.flatnonzero(todo & known[:, parent])
            if not len(rows):
                continue
            r = rays[t_all[rows], view[rows, child], child]
            radius = np.full(len(rows), lengths[(parent, child)])
            P = _on_sphere(r[:, :3], r[:, 3:], best[rows, parent], radius, prior[rows, child],
                           cfg.max_miss)  # fmt: skip
            ok = np.isfinite(P).all(-1)
            rows, P = rows[ok], P[ok]
            out[rows, child] = P
            if truth is None:
                best[rows, child] = P
            known[rows, child] = placed[rows, child] = True
            todo[rows] = False
    return out, placed


def main() -> None:
    import torch

    from rmpl.data.sequences import SequenceBank, SequenceSource
    from rmpl.training.temporal import load_temporal

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank")
    ap.add_argument("model", nargs="?", default="src/rmpl/weights/temporal")
    ap.add_argument("--windows", type=int, default=64)
    ap.add_argument("--views", default="2,3")
    a = ap.parse_args()
    torch.set_num_threads(2)
    _, val = SequenceBank.load(a.bank).split(["03"])
    model = load_temporal(a.model)[0]
    model.use_onnx()
    print("| views | parents and lengths | joints placed | temporal model (mean / median mm) "
          "| placed on the ray (mean / median mm) |")  # fmt: skip
    print("|---|---|---:|---:|---:|")
    for v in [int(x) for x in a.views.split(",")]:
        b = SequenceSource(val, seed=777).batch(a.windows, model.config.window, v, train=False)
        with torch.no_grad():
            pts = model(*(torch.from_numpy(x) for x in (b.rays, b.scores, b.times)))[0].numpy()
        for label, oracle in (("from the 2D", False), ("true (upper bound)", True)):
            before, after = [], []
            for i in range(len(pts)):
                truth = b.target[i] if oracle else None
                out, placed = fit_single_view(b.rays[i], b.scores[i], pts[i], truth=truth)
                before.append(np.linalg.norm(pts[i] - b.target[i], axis=-1)[placed])
                after.append(np.linalg.norm(out - b.target[i], axis=-1)[placed])
            e0, e1 = np.concatenate(before) * 1000, np.concatenate(after) * 1000
            print(f"| {v} | {label} | {len(e0)} | {e0.mean():.1f} / {np.median(e0):.1f} "
                  f"| {e1.mean():.1f} / {np.median(e1):.1f} |")  # fmt: skip


if __name__ == "__main__":
    main()
