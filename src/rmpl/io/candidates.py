"""Unassociated 2D part candidates of one image with their part affinities (OpenPose's
output before grouping), as the Shelf and Campus detections come; grouped into people by
:func:`rmpl.pipeline.association.group_people`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BODY25_LIMBS", "Candidates"]

#: The 26 BODY_25 part-affinity fields of OpenPose, as (joint a, joint b) in its order.
#: 24 of them span the limb tree; (2, 17) and (5, 18) (shoulder-ear) are redundant links.
BODY25_LIMBS: tuple[tuple[int, int], ...] = (
    (1, 8),
    (9, 10),
    (10, 11),
    (8, 9),
    (8, 12),
    (12, 13),
    (13, 14),
    (1, 2),
    (2, 3),
    (3, 4),
    (2, 17),
    (1, 5),
    (5, 6),
    (6, 7),
    (5, 18),
    (1, 0),
    (0, 15),
    (0, 16),
    (15, 17),
    (16, 18),
    (14, 19),
    (19, 20),
    (14, 21),
    (11, 22),
    (22, 23),
    (11, 24),
)


@dataclass(frozen=True)
class Candidates:
    """Unassociated part candidates of one image, with their part affinities.

    Attributes:
        points: one array per joint, shape (n_j, 3): x, y in pixels and the detector score.
        affinities: one array per limb, shape (n_a, n_b): the affinity of every pair of
            candidates of the limb's two joints (0 = not connected).
        limbs: the (a, b) joint pairs of ``affinities``, e.g. :data:`BODY25_LIMBS`.
        skeleton: name of the joint set of ``points`` in :data:`rmpl.skeleton.SKELETONS`.
    """

    points: tuple[np.ndarray, ...]
    affinities: tuple[np.ndarray, ...]
    limbs: tuple[tuple[int, int], ...] = BODY25_LIMBS
    skeleton: str = "body25"

    def __post_init__(self) -> None:
        pts = tuple(np.asarray(p, dtype=float) for p in self.points)
        pts = tuple(p.reshape(0, 3) if p.size == 0 else p for p in pts)
        for j, p in enumerate(pts):
            if p.ndim != 2 or p.shape[1] != 3:
                raise ValueError(f"candidates of joint {j} must have shape (n, 3), got {p.shape}")
        aff = tuple(np.asarray(a, dtype=float) for a in self.affinities)
        if len(aff) != len(self.limbs):
            raise ValueError(
                f"need one affinity matrix per limb ({len(self.limbs)}), got {len(aff)}"
            )
        for (a, b), A in zip(self.limbs, aff, strict=True):
            if max(a, b) >= len(pts):
                raise ValueError(f"limb ({a}, {b}) is outside the {len(pts)} joints")
            if A.shape != (len(pts[a]), len(pts[b])):
                raise ValueError(
                    f"affinities of limb ({a}, {b}) must have shape "
                    f"{(len(pts[a]), len(pts[b]))}, got {A.shape}"
                )
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "affinities", aff)
        object.__setattr__(self, "limbs", tuple((int(a), int(b)) for a, b in self.limbs))

    @property
    def num_joints(self) -> int:
        return len(self.points)
