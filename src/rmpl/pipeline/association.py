"""Multi-person association: 2D part candidates -> 2D people -> 3D people.

Three steps, each usable on its own and none tied to a dataset:

1. :func:`group_people` parses the unassociated part candidates of one image into people
   with part-affinity scores (a greedy, OpenPose-style parse over the limbs).
2. :func:`associate` groups the 2D people of several calibrated views into 3D people by
   geometry (ray-to-ray distances, constrained average-linkage clustering). Its output,
   per 3D person, is the triangulation/lifter input: keypoints (V, J, 2) NaN where the
   person is not seen, scores (V, J) 0 there.
3. :func:`match_poses` matches 3D estimates to ground-truth people for evaluation
   (Hungarian assignment on the mean joint distance, with a gate).

Shape glossary: ``V`` views, ``J`` joints, ``P`` 2D people in one view, ``N`` 3D people
(or all 2D people of a frame, where said), ``M`` ground-truth people, ``L`` limbs.
Pixels from the top-left; metres.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.geometry.rays import rays_from_keypoints
from rmpl.skeleton import (
    BY_COUNT,
    COCO17,
    SKELETONS,
    convert,
    convert_scores,
    embed,
    embed_scores,
)

__all__ = [
    "BODY25_LIMBS",
    "Association",
    "AssociationConfig",
    "Candidates",
    "GroupingConfig",
    "associate",
    "associate_candidates",
    "cluster_people",
    "coco17_joints",
    "duplicate_people",
    "group_people",
    "match_poses",
    "ray_distance_cost",
]

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


@dataclass(frozen=True)
class GroupingConfig:
    """Thresholds of :func:`group_people`.

    Attributes:
        min_part_score: candidates scoring lower are ignored.
        min_affinity: limb connections with a lower part-affinity score are ignored.
        min_parts: people with fewer joints are dropped (OpenPose drops < 4 as well).
        min_mean_score: people whose mean joint score is lower are dropped.
    """

    min_part_score: float = 0.05
    min_affinity: float = 0.1
    min_parts: int = 4
    min_mean_score: float = 0.3


def _limb_connections(candidates: Candidates, cfg: GroupingConfig) -> list[tuple]:
    """Per limb, greedy one-to-one connections by descending affinity (ties: the first
    candidate pair in row-major order).

    Returns:
        (affinity, joint a, candidate i, joint b, candidate j) tuples.
    """
    edges = []
    score = [(p[:, 2] >= cfg.min_part_score).tolist() for p in candidates.points]
    for (a, b), A in zip(candidates.limbs, candidates.affinities, strict=True):
        if A.size == 0:
            continue
        ok_a, ok_b = score[a], score[b]
        # plain Python: the matrices are a few candidates square
        pairs = [
            (-s, i, j)
            for i, row in enumerate(A.tolist())
            if ok_a[i]
            for j, s in enumerate(row)
            if ok_b[j] and s >= cfg.min_affinity
        ]
        if any(s == -math.inf for s, _, _ in pairs):  # an infinite affinity stops the limb
            continue
        pairs.sort()
        used_a, used_b = set(), set()
        for s, i, j in pairs:
            if i not in used_a and j not in used_b:
                used_a.add(i)
                used_b.add(j)
                edges.append((-s, a, i, b, j))
    return edges


def group_people(
    candidates: Candidates, config: GroupingConfig | None = None, output: str | None = "coco17"
) -> tuple[np.ndarray, np.ndarray]:
    """Group one image's part candidates into people with part affinities.

    A greedy parse in the spirit of OpenPose: per limb, candidate pairs are connected one
    to one in descending affinity; then all connections of all limbs, strongest first,
    grow people: a connection starts a person, extends the person owning one end, or
    merges the two people owning its ends, unless that would give a person two
    candidates of one joint. People with fewer than ``min_parts`` joints or a mean score
    below ``min_mean_score`` are dropped.

    Args:
        candidates: the image's candidates and affinities.
        config: thresholds; defaults to :class:`GroupingConfig`.
        output: joint set of the result: a joint set's name (default COCO-17), ``"auto"``
            the richest one the candidates give (:func:`rmpl.io.keypoints.richest`:
            HALPE-26 for BODY_25, whose neck, mid-hip and feet it keeps, as ``rmpl run``
            asks), or None for ``candidates.skeleton``. The grouping itself is the same
            whatever the output.

    Returns:
        keypoints, shape (P, J, 2), pixels, NaN where missing; scores, shape (P, J),
        0 where missing. People are sorted by descending total score.

    >>> pts = [np.zeros((0, 3))] * 25
    >>> pts[1] = np.array([[10.0, 10, 0.9]]); pts[8] = np.array([[10.0, 50, 0.8]])
    >>> aff = [np.zeros((len(pts[a]), len(pts[b]))) for a, b in BODY25_LIMBS]
    >>> aff[0] = np.array([[0.7]])  # neck - mid-hip
    >>> kp, sc = group_people(Candidates(tuple(pts), tuple(aff)),
    ...                       GroupingConfig(min_parts=2), output=None)
    >>> kp.shape, sc[0, [1, 8]].tolist()
    ((1, 25, 2), [0.9, 0.8])
    """
    cfg = config or GroupingConfig()
    J = candidates.num_joints
    owner = [[-1] * len(p) for p in candidates.points]  # person of each candidate
    people: list[list[int] | None] = []  # per person: candidate index per joint, -1 none
    edges = sorted(_limb_connections(candidates, cfg), key=lambda e: -e[0])
    for _, a, i, b, j in edges:
        pa, pb = owner[a][i], owner[b][j]
        if pa < 0 and pb < 0:
            person = [-1] * J
            person[a], person[b] = i, j
            owner[a][i] = owner[b][j] = len(people)
            people.append(person)
        elif pa >= 0 and pb < 0:
            if people[pa][b] < 0:
                people[pa][b], owner[b][j] = j, pa
        elif pb >= 0 and pa < 0:
            if people[pb][a] < 0:
                people[pb][a], owner[a][i] = i, pb
        elif pa != pb and not any(
            x >= 0 and y >= 0 for x, y in zip(people[pa], people[pb], strict=True)
        ):
            for k, c in enumerate(people[pb]):
                if c >= 0:
                    people[pa][k] = c
                    owner[k][c] = pa
            people[pb] = None
    kps, scs = [], []
    for person in people:
        if person is None:
            continue
        have = [k for k, c in enumerate(person) if c >= 0]
        if len(have) < cfg.min_parts:
            continue
        kp, sc = np.full((J, 2), np.nan), np.zeros(J)
        for k in have:
            kp[k], sc[k] = candidates.points[k][person[k], :2], candidates.points[k][person[k], 2]
        if sc[have].mean() >= cfg.min_mean_score:
            kps.append(kp)
            scs.append(sc)
    kp, sc = np.array(kps).reshape(-1, J, 2), np.array(scs).reshape(-1, J)
    order = np.argsort(-sc.sum(-1), kind="stable")
    kp, sc = kp[order], sc[order]
    return _output_joints(kp, sc, candidates.skeleton, output)


def _output_joints(kp: np.ndarray, sc: np.ndarray, native: str, output: str | None):
    """(P, J, 2), (P, J) in ``native`` -> ``output`` (see :func:`group_people`)."""
    from rmpl.io.keypoints import richest

    if output == "auto":
        output = richest(native)
    if output is None or output == native:
        return kp, sc
    if output == "halpe26":  # by name: joints the native set lacks are missing
        return embed(kp, native, output), embed_scores(sc, native, output)
    kp = convert(kp, native, output)
    return kp, np.where(np.isfinite(kp).all(-1), convert_scores(sc, native, output), 0.0)


#: Default :attr:`AssociationConfig.duplicate_tolerance`, chosen on the held-out MHP scenes
#: (``data/mhp_scenes_heldout``, every 4-view subset, the per-frame lifter): of 0.1 ... 0.5
#: in steps of 0.1, the fewest missed + spurious people (481 of 4884 at 0.2 and 0.3, 483
#: off, 492 at 0.5), ties to the smaller value.
DUPLICATE_TOLERANCE = 0.2


@dataclass(frozen=True)
class AssociationConfig:
    """Thresholds of :func:`associate`.

    Attributes:
        min_score: a joint enters the cost of a pair of 2D people when both its scores
            are at least this.
        min_common_joints: pairs with fewer such joints have no cost (cannot be linked
            directly, only through a third view).
        max_cost: largest average-linkage cost (mean ray-to-ray distance, metres) at
            which two clusters are merged.
        clip: per-joint ray distances are clipped to this (metres); joints whose rays
            meet behind a camera count as ``clip``.
        min_views: 3D people seen in fewer views are dropped (2 = triangulable).
        duplicate_tolerance: drop 3D people that duplicate another (one person split into
            clusters that share no view, see :func:`duplicate_people`): a 3D person whose
            triangulated limb joints reproject, in every view the other uses, within this
            fraction of the other's size (median pixel distance over the joints / the
            larger side of the other's 2D box) of the other's detection. Of such a pair the
            one with fewer views goes (ties: the larger internal ray cost). None: off.
    """

    min_score: float = 0.3
    min_common_joints: int = 3
    max_cost: float = 0.15
    clip: float = 1.0
    min_views: int = 2
    duplicate_tolerance: float | None = DUPLICATE_TOLERANCE

    def __post_init__(self) -> None:
        tol = self.duplicate_tolerance
        if tol is not None and not (isinstance(tol, int | float) and tol > 0):
            raise ValueError(f"duplicate_tolerance must be None (off) or > 0, got {tol!r}")


@dataclass(frozen=True)
class Association:
    """3D people found across views: the input of triangulation or the lifter.

    Attributes:
        keypoints: shape (N, V, J, 2), pixels; NaN where a person is not seen.
        scores: shape (N, V, J); 0 where a person is not seen.
        members: shape (N, V), int: the index of the person's 2D detection in each
            view's input list, -1 where not seen.
    """

    keypoints: np.ndarray
    scores: np.ndarray
    members: np.ndarray

    def __len__(self) -> int:
        return len(self.members)


def _ray_distances(rays: np.ndarray, clip: float) -> np.ndarray:
    """Distance between every pair of rays, clipped.

    Args:
        rays: shape (N, J, 6), unit directions.

    Returns:
        shape (N, N, J), metres; ``clip`` where the closest approach is behind a camera.
    """
    o, d = rays[..., :3], rays[..., 3:]
    oi, di, oj, dj = o[:, None], d[:, None], o[None], d[None]  # (N, 1, J, 3), (1, N, J, 3)
    w0 = oi - oj
    b = (di * dj).sum(-1)
    dw, ew = (di * w0).sum(-1), (dj * w0).sum(-1)
    denom = 1.0 - b * b
    parallel = denom < 1e-9
    safe = np.where(parallel, 1.0, denom)
    s = np.where(parallel, 0.0, (b * ew - dw) / safe)  # along ray i
    t = np.where(parallel, ew, (ew - b * dw) / safe)  # along ray j
    gap = np.linalg.norm(w0 + s[..., None] * di - t[..., None] * dj, axis=-1)
    behind = (s <= 0) | (t <= 0)
    return np.minimum(np.where(behind, clip, gap), clip)


def ray_distance_cost(
    keypoints: np.ndarray,
    scores: np.ndarray,
    views: np.ndarray,
    rig: Rig,
    config: AssociationConfig | None = None,
) -> np.ndarray:
    """Pairwise cost of 2D people: mean ray-to-ray distance over jointly confident joints.

    Args:
        keypoints: all 2D people of a frame, shape (N, J, 2), pixels.
        scores: shape (N, J).
        views: the view of each person, shape (N,), int indices into ``rig``.
        rig: the cameras.
        config: thresholds; defaults to :class:`AssociationConfig`.

    Returns:
        shape (N, N), metres; NaN for pairs in the same view or with fewer than
        ``min_common_joints`` jointly confident joints.
    """
    cfg = config or AssociationConfig()
    views = np.asarray(views, dtype=int)
    kp = np.asarray(keypoints, dtype=float)
    sc = np.asarray(scores, dtype=float)
    ok = np.isfinite(kp).all(-1) & (np.nan_to_num(sc) >= cfg.min_score)  # (N, J)
    rays = rays_from_keypoints(
        np.where(ok[..., None], kp, 0.0),
        K=rig.K[views],
        R=rig.R[views],
        t=rig.t[views],
        dist=rig.dist[views],
    )  # (N, J, 6): the N people play the role of views
    dist = _ray_distances(rays, cfg.clip)  # (N, N, J)
    both = ok[:, None] & ok[None]
    count = both.sum(-1)
    with np.errstate(invalid="ignore"):
        cost = np.where(both, dist, 0.0).sum(-1) / count
    undefined = (count < cfg.min_common_joints) | (views[:, None] == views[None])
    return np.where(undefined, np.nan, cost)


def cluster_people(cost: np.ndarray, views: np.ndarray, max_cost: float) -> np.ndarray:
    """Constrained average-linkage clustering of 2D people into 3D people.

    Starting from one cluster per 2D person, repeatedly merge the two clusters with the
    lowest average linkage (mean of the defined costs between their members) while it
    is at most ``max_cost``, never merging two clusters that share a view.

    Args:
        cost: pairwise costs, shape (N, N); NaN = undefined (ignored by the mean; a
            pair of clusters with no defined cost is never merged).
        views: the view of each person, shape (N,), int.
        max_cost: merge threshold, in the units of ``cost``.

    Returns:
        Cluster label of each person, shape (N,), int in 0..C-1.

    >>> c = np.array([[np.nan, 0.1, 0.9], [0.1, np.nan, 0.8], [0.9, 0.8, np.nan]])
    >>> cluster_people(c, np.array([0, 1, 1]), 0.5).tolist()
    [0, 0, 1]
    """
    cost = np.asarray(cost, dtype=float)
    views = np.asarray(views, dtype=int)
    N = len(views)
    if N == 0:
        return np.zeros(0, dtype=int)
    defined = np.isfinite(cost)
    total, count = np.where(defined, cost, 0.0), defined.astype(float)
    seen = np.eye(views.max() + 1, dtype=int)[views]  # (N, V): views of each cluster
    active = np.ones(N, dtype=bool)
    labels = np.arange(N)
    while True:
        with np.errstate(invalid="ignore", divide="ignore"):
            link = np.where(count > 0, total / count, np.inf)
        blocked = (seen @ seen.T > 0) | ~active[:, None] | ~active[None]
        link[blocked] = np.inf
        k = int(np.argmin(link))
        i, j = divmod(k, N)
        if not link[i, j] <= max_cost:
            break
        total[i] += total[j]
        total[:, i] += total[:, j]
        count[i] += count[j]
        count[:, i] += count[:, j]
        seen[i] |= seen[j]
        active[j] = False
        labels[labels == j] = i
    return np.unique(labels, return_inverse=True)[1].reshape(N)


def _check_people(keypoints, scores, num_views: int):
    if len(keypoints) != num_views or len(scores) != num_views:
        raise InputError(
            None,
            "keypoints/scores",
            f"one entry per camera of the rig ({num_views})",
            f"{len(keypoints)} keypoint and {len(scores)} score entries",
        )
    kps = [np.asarray(k, dtype=float) for k in keypoints]
    scs = [np.asarray(s, dtype=float) for s in scores]
    J = next((k.shape[1] for k in kps if k.ndim == 3), 0)
    for v, (k, s) in enumerate(zip(kps, scs, strict=True)):
        if k.ndim != 3 or k.shape[1:] != (J, 2):
            raise InputError(None, f"keypoints[{v}]", f"shape (P, {J}, 2)", k.shape)
        if s.shape != k.shape[:2]:
            raise InputError(None, f"scores[{v}]", f"shape {k.shape[:2]} (P, J)", s.shape)
    return kps, scs, J


def coco17_joints(num_joints: int, skeleton: str | None = None) -> list[int]:
    """Indices of the COCO-17 joints, in COCO order, of a joint set that has them all, else
    of every joint: the joints :func:`associate` compares.

    Args:
        num_joints: J of the keypoints.
        skeleton: their joint set; None: COCO-17 for 17 joints, HALPE-26 for 26.

    >>> coco17_joints(26) == list(range(17)), coco17_joints(12) == list(range(12))
    (True, True)
    """
    if skeleton is None:
        skeleton = BY_COUNT.get(num_joints)
    if skeleton is not None:
        if skeleton not in SKELETONS:
            raise InputError(None, "skeleton", f"None or one of {sorted(SKELETONS)}", skeleton)
        sk = SKELETONS[skeleton]
        if num_joints and sk.num_joints != num_joints:
            raise InputError(
                None, "skeleton", f"a joint set of {num_joints} joints", f"{skeleton!r}"
            )
        if set(COCO17.joints) <= set(sk.joints):
            return sk.indices(COCO17.joints)
    return list(range(num_joints))


def associate(
    keypoints: Sequence[np.ndarray],
    scores: Sequence[np.ndarray],
    rig: Rig,
    config: AssociationConfig | None = None,
    skeleton: str | None = None,
) -> Association:
    """Associate the 2D people of V calibrated views into 3D people.

    Every pair of 2D people in two different views costs the mean, over the joints both
    see with score >= ``min_score``, of the distance between the two joints' camera rays
    (metres; see :func:`ray_distance_cost`). :func:`cluster_people` then groups them
    (average linkage up to ``max_cost``, at most one 2D person per view per 3D person).
    3D people seen in fewer than ``min_views`` views are dropped.

    The cost uses the COCO-17 joints of a joint set that has them all (HALPE-26's first
    17), so that a detector's feet, neck or head top change no decision: a COCO-17 input
    and the same people with extra joints are grouped alike. Every joint is carried into
    the result.

    Args:
        keypoints: per view, shape (P_v, J, 2), pixels (NaN = missing joint).
        scores: per view, shape (P_v, J).
        rig: the V cameras, in the order of ``keypoints``.
        config: thresholds; defaults to :class:`AssociationConfig`.
        skeleton: the joint set of ``keypoints``; None: COCO-17 for 17 joints, HALPE-26 for
            26, otherwise every joint enters the cost.

    Returns:
        :class:`Association` with the input's J joints, people sorted by descending number
        of views, then by descending total score (of the joints the cost uses).

    Raises:
        InputError: when the per-view arrays do not match the rig or each other.
    """
    cfg = config or AssociationConfig()
    V = len(rig)
    kps, scs, J = _check_people(keypoints, scores, V)
    views = np.concatenate([np.full(len(k), v) for v, k in enumerate(kps)]).astype(int)
    index = np.concatenate([np.arange(len(k)) for k in kps]).astype(int)
    kp_all = np.concatenate(kps).reshape(-1, J, 2)
    sc_all = np.where(np.isfinite(kp_all).all(-1), np.nan_to_num(np.concatenate(scs)), 0.0)
    sc_all = sc_all.reshape(-1, J)
    use = coco17_joints(J, skeleton)
    cost = ray_distance_cost(kp_all[:, use], sc_all[:, use], views, rig, cfg)
    labels = cluster_people(cost, views, cfg.max_cost)
    C = int(labels.max()) + 1 if len(labels) else 0
    members = np.full((C, V), -1, dtype=int)
    members[labels, views] = index
    out_kp = np.full((C, V, J, 2), np.nan)
    out_sc = np.zeros((C, V, J))
    out_kp[labels, views] = kp_all
    out_sc[labels, views] = sc_all
    keep = (members >= 0).sum(-1) >= cfg.min_views
    if cfg.duplicate_tolerance is not None and keep.sum() > 1:
        found = Association(out_kp[keep], out_sc[keep], members[keep])
        keep[np.flatnonzero(keep)] = duplicate_people(found, rig, cfg, skeleton)
    order = np.lexsort((-out_sc[..., use].sum((-1, -2)), -(members >= 0).sum(-1)))
    order = order[keep[order]]
    return Association(out_kp[order], out_sc[order], members[order])


def duplicate_people(
    people: Association,
    rig: Rig,
    config: AssociationConfig | None = None,
    skeleton: str | None = None,
) -> np.ndarray:
    """Which 3D people to keep when one person was split into clusters sharing no view.

    A poor detection in one view can pair better with a wrong detection (two people
    overlapping) than with the rest of its own person; the person then comes out twice,
    as two clusters of different views. Person ``i`` duplicates person ``j`` when the two
    share no view and, in every view ``j`` uses, ``i``'s 3D (the confidence-weighted DLT
    of its twelve limb joints, :data:`rmpl.skeleton.KP_STAR`) reprojects within
    ``duplicate_tolerance`` of ``j``'s size onto ``j``'s detection: the median pixel distance over
    the joints both have, divided by the larger side of ``j``'s 2D box there (of its
    COCO-17 joints, so that a detector's extra joints change no decision). A view of
    ``j`` with fewer than ``min_common_joints`` such joints, or a point behind its camera,
    decides "not a duplicate". Of a duplicate pair (either way round) the person with fewer
    views goes; with as many, the one whose views agree less (the larger mean ray-to-ray
    cost between its views, :func:`ray_distance_cost`). People are dropped greedily, the
    weakest first, and only for a person still kept.

    Args:
        people: the 3D people of one frame, as :func:`associate` finds them.
        rig: the V cameras.
        config: thresholds (``duplicate_tolerance``, ``min_score``,
            ``min_common_joints``); a tolerance of None keeps everyone.
        skeleton: the joint set of ``people.keypoints``; None: by its joint count.

    Returns:
        keep, shape (N,), bool.
    """
    from rmpl.geometry.triangulate import triangulate
    from rmpl.skeleton import KP_STAR

    cfg = config or AssociationConfig()
    N, V, J = people.keypoints.shape[:3]
    keep = np.ones(N, dtype=bool)
    if cfg.duplicate_tolerance is None or N < 2:
        return keep
    seen = people.members >= 0  # (N, V)
    disjoint = ~(seen.astype(int) @ seen.T.astype(int) > 0)  # (N, N) share no view
    np.fill_diagonal(disjoint, False)
    if not disjoint.any():
        return keep
    limbs = [coco17_joints(J, skeleton)[k] for k in KP_STAR] if J >= 17 else list(range(J))
    kp, sc = people.keypoints[:, :, limbs], people.scores[:, :, limbs]  # (N, V, L, ·)
    points = triangulate(kp, sc, rig, min_score=cfg.min_score).points  # (N, L, 3)
    uv = rig.project(points)  # (N, V, L, 2)
    depth = np.einsum("vij,nlj->nvli", rig.R, points)[..., 2] + rig.t[None, :, None, 2]
    sure = np.isfinite(kp).all(-1) & (sc >= cfg.min_score)  # (N, V, L)
    use = coco17_joints(J, skeleton)  # the joints association decides on
    box = people.keypoints[:, :, use]
    box = np.where(np.isfinite(box) & (people.scores[:, :, use] > 0)[..., None], box, np.nan)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # views a person is not in: NaN
        size = np.nanmax(np.nanmax(box, -2) - np.nanmin(box, -2), -1)  # (N, V)

    def lands_on(i: int, j: int) -> bool:
        """``i``'s 3D lands on ``j``'s detection in every view ``j`` uses."""
        for v in np.flatnonzero(seen[j]):
            ok = sure[j, v] & np.isfinite(uv[i, v]).all(-1) & (depth[i, v] > 0)
            if ok.sum() < cfg.min_common_joints or not size[j, v] > 0:
                return False
            gap = np.linalg.norm(uv[i, v][ok] - kp[j, v][ok], axis=-1)
            if not np.median(gap) / size[j, v] <= cfg.duplicate_tolerance:
                return False
        return True

    num_views = seen.sum(-1)
    spread = np.full(N, np.inf)  # mean ray cost between a person's own views
    for n in range(N):
        vs = np.flatnonzero(seen[n])
        c = ray_distance_cost(people.keypoints[n, vs][:, use], people.scores[n, vs][:, use],
                              vs, rig, cfg)  # fmt: skip
        if np.isfinite(c).any():
            spread[n] = np.nanmean(c)
    weakest_first = sorted(range(N), key=lambda n: (num_views[n], -spread[n]))
    rank = np.argsort(weakest_first)  # larger rank = stronger
    for i in weakest_first:
        for j in np.flatnonzero(disjoint[i] & keep):
            if rank[j] > rank[i] and (lands_on(i, j) or lands_on(j, i)):
                keep[i] = False
                break
    return keep


def associate_candidates(
    candidates: Sequence[Candidates],
    rig: Rig,
    grouping: GroupingConfig | None = None,
    association: AssociationConfig | None = None,
    output: str = "coco17",
) -> Association:
    """Group every view's part candidates (:func:`group_people`), then :func:`associate`.

    Args:
        candidates: one :class:`Candidates` per camera of ``rig``.
        rig: the V cameras.
        grouping, association: thresholds of the two steps.
        output: joint set of the result: a name in :data:`rmpl.skeleton.SKELETONS`
            (default COCO-17) or ``"auto"`` (the richest the candidates give, see
            :func:`group_people`).

    Returns:
        :class:`Association` in the ``output`` joint set (people grouped on its COCO-17
        joints, see :func:`associate`).
    """
    if output != "auto" and output not in SKELETONS:
        raise InputError(None, "output", f"'auto' or one of {sorted(SKELETONS)}", output)
    people = [group_people(c, grouping, output) for c in candidates]
    skeleton = None
    if candidates:
        from rmpl.io.keypoints import richest

        skeleton = richest(candidates[0].skeleton) if output == "auto" else output
    return associate(
        [p[0] for p in people], [p[1] for p in people], rig, association, skeleton=skeleton
    )


def match_poses(
    pred: np.ndarray,
    gt: np.ndarray,
    max_distance: float = 0.5,
    joints: Sequence[int] | None = None,
) -> np.ndarray:
    """Match 3D estimates to ground-truth people (for evaluation).

    The cost of a pair is the mean Euclidean distance over the joints finite in both
    (infinite when there are none); the Hungarian algorithm minimises the total cost
    and pairs costing more than ``max_distance`` are then left unmatched.

    Args:
        pred: estimates, shape (N, J, 3), metres.
        gt: ground truth, shape (M, J, 3); an absent person is all NaN.
        max_distance: gate on the mean joint distance, metres.
        joints: joint indices used for the cost; all when None.

    Returns:
        For each ground-truth person the index of its estimate, shape (M,), or -1.

    >>> gt = np.zeros((2, 4, 3)); gt[1] += 2.0
    >>> match_poses(gt[::-1] + 0.01, gt).tolist()
    [1, 0]
    """
    from scipy.optimize import linear_sum_assignment

    pred, gt = np.asarray(pred, dtype=float), np.asarray(gt, dtype=float)
    if joints is not None:
        pred, gt = pred[..., list(joints), :], gt[..., list(joints), :]
    match = np.full(len(gt), -1, dtype=int)
    if len(pred) == 0 or len(gt) == 0:
        return match
    err = np.linalg.norm(pred[:, None] - gt[None], axis=-1)  # (N, M, J)
    ok = np.isfinite(err)
    with np.errstate(invalid="ignore"):
        cost = np.where(ok, err, 0.0).sum(-1) / ok.sum(-1)
    cost = np.where(ok.any(-1), cost, np.inf)
    big = 1e6 + np.nanmax(np.where(np.isfinite(cost), cost, 0.0))
    rows, cols = linear_sum_assignment(np.where(np.isfinite(cost), cost, big))
    good = cost[rows, cols] <= max_distance
    match[cols[good]] = rows[good]
    return match
