"""Do the views agree on each person? A loud failure when they do not.

A multi-view result is only as good as the assumption that every view's 2D shows the same
person. When a detector picks different people in different views (a single-person
detector in a room with two people), association and lifting still produce one 3D person:
a blend that lies on nobody. This module checks every tracked person, frame and view.

Definitions (all per person, frame and view):

- **The person's size in a view**, ``size`` pixels: the height the person would have in
  that image standing upright at the depth of its 3D centroid, ``f * H / depth`` (``f``
  the camera's mean focal length in pixels, ``H`` the person's estimated height, else
  1.70 m). It does not shrink when joints are missing or when the person bends or lies
  down, as a bounding box would. Where that centroid is behind the camera (a 3D so wrong
  that it lies beyond the camera that sees the person), the larger side of the bounding box
  of the view's own 2D is used instead.
- **The consensus**: the set of views whose 2D of the person agree with each other. For
  every pair of views with 2D, the pair's 2D is triangulated (confidence-weighted DLT) and
  reprojected into every view; the pair is consistent when both its views lie within the
  threshold, and its consensus is every view within the threshold. Of the consistent pairs,
  the one with the lowest truncated cost wins: the sum over the views with 2D of their
  error, capped at the threshold (MSAC, Torr and Zisserman 2000). Counting views within
  the threshold alone (RANSAC) can prefer a pair of two different people whose
  triangulation lands between them, within the threshold of every view.
- **A view's error**, as a fraction of ``size``: the median over joints (at least 5, with
  2D in that view) of the pixel distance between the view's 2D and the reprojection of the
  3D triangulated from the OTHER views of the consensus (leave-one-view-out). A view in a
  two-view consensus is compared with the pair's triangulation. A person no pair of whose
  views is consistent is compared with the triangulation of all its other views (of both,
  with two). A joint triangulated behind the camera counts as infinitely far.
- **Left/right swapped**: a disagreeing view whose 2D, with its left and right joints
  exchanged (the skeleton's mirror pairs), lies within the threshold and at most half as far
  as it did (another person close by can also lie within the threshold once mirrored): the
  detector confused
  the person's sides in that view (frequent in turns and cartwheels), rather than seeing
  somebody else. Reported beside the disagreement.
- **The status** (:class:`rmpl.io.poses.ViewStatus`): ``agrees`` when the error is at most
  the threshold, ``disagrees`` when above it (and every view of a person without a
  consistent pair disagrees); ``unchecked`` when the view has 2D but fewer than 5 joints
  can be compared or no other view has 2D; ``missed`` when the view has no 2D of the
  person although its 3D centroid projects inside the image (occluded, or not detected);
  ``out_of_view`` when it projects outside the image or behind the camera; ``absent``
  when the person has no 3D in that frame.

**The joints compared are COCO-17's**, also when the 2D or the 3D has more (HALPE-26's
head top, neck, mid-hip and feet are left out; a joint set without all of COCO-17 is
compared on every joint). The threshold below and the 5-joint minimum were set for
COCO-17's median; six foot points gathered at the ankles would pull the median towards the
feet, where a neighbour's feet can lie closer than his body, and move the centroid that sets
the size; and every existing run keeps its statuses. The 3D may also have another joint set
than the 2D (a COCO-17 model on HALPE-26 2D, or the reverse); COCO-17 is in both.

**Threshold: 0.2 of the person's size** (34 cm at the person's distance for 1.70 m).
A detector's error on a person it has found is a few per cent of the person's height
(COCO's keypoint similarity scores a joint with a tolerance of 2.5-10.7% of the object's
scale), and the median over joints is smaller still; another person standing beside
them is at least a shoulder width away, 0.26 of the height (Drillis and Contini's
proportions, see :mod:`rmpl.anthropometry`). 0.2 lies between the two. It is a
fraction, so it holds for near and far people and any image size.

**The loud failure.** A frame is *contested* for a person when at least 2 of its views are
compared (agree or disagree) and at least one of them disagrees: the person's 3D in that
frame is built from 2D that does not belong together. A person *fails* when it is contested
in more than half of its compared frames. "Most" is counted in frames, not in views per
frame, on purpose: in the motivating real case (``Demo_MultiPerson``, two people, a
single-person detector, 4 cameras) the detector's choice rotates between the cameras, so in
most frames only one camera of four shows the other person, yet the 3D is a blend in 85 of
100 frames; a rule requiring half of the views to disagree in a frame flags 45 of them and
would let that run pass. ``rmpl run`` then still writes every output (so the result can be
inspected), logs a WARNING banner naming the person, and its views and frames in
``report.md``, and exits with status :data:`EXIT_VIEWS_DISAGREE` (3), distinct from bad
input (2). Fewer disagreements (one camera seeing someone else now and then) are logged at
WARNING with the views and frames, and do not change the exit status. A camera whose
calibration is off disagrees in every frame, and fails the run the same way.

Shape glossary: ``T`` frames, ``P`` people (tracks), ``V`` views, ``J`` joints. Pixels,
metres.
"""

from __future__ import annotations

import itertools
import logging
import warnings
from dataclasses import dataclass

import numpy as np

from rmpl.geometry.camera import Rig
from rmpl.geometry.triangulate import triangulate_points
from rmpl.io.poses import ViewStatus
from rmpl.pipeline.association import coco17_joints

__all__ = [
    "EXIT_VIEWS_DISAGREE",
    "Consistency",
    "ConsistencyConfig",
    "Disagreement",
    "check_views",
    "format_ranges",
    "frame_ranges",
    "held_out_px",
    "moved_cameras",
    "person_2d",
]

log = logging.getLogger(__name__)

#: Exit status of ``rmpl run`` when a person fails the check (outputs are written).
EXIT_VIEWS_DISAGREE = 3
#: A camera "moved since calibration" when its held-out error exceeds both this many pixels
#: and :data:`MOVED_RATIO` times the median of the other cameras' (a rule fixed in advance,
#: shared by ``rmpl calibrate --check`` and the run report).
MOVED_PX, MOVED_RATIO = 10.0, 3.0

#: Checks of at least this many person-frames (T x P) show a progress bar.
PROGRESS_FROM = 5000

#: Nominal standing height, metres, for a person whose height is unknown.
NOMINAL_HEIGHT = 1.70


@dataclass(frozen=True)
class ConsistencyConfig:
    """Settings of :func:`check_views` (see the module docstring).

    Attributes:
        threshold: a view disagrees when its error exceeds this fraction of the person's size.
        min_joints: joints a view's error needs (fewer: ``unchecked``).
        most_frames: a person fails when more than this fraction of its compared frames
            are contested (a compared view disagrees).
    """

    threshold: float = 0.2
    min_joints: int = 5
    most_frames: float = 0.5

    def __post_init__(self) -> None:
        if not self.threshold > 0:
            raise ValueError(f"threshold must be > 0, got {self.threshold}")
        if self.min_joints < 1:
            raise ValueError(f"min_joints must be >= 1, got {self.min_joints}")
        if not 0 <= self.most_frames <= 1:
            raise ValueError(f"most_frames must be in [0, 1], got {self.most_frames}")


@dataclass(frozen=True)
class Disagreement:
    """One view disagreeing with one person: ``person`` and ``view`` are indices,
    ``ranges`` inclusive (first, last) frame numbers, ``frames`` their count,
    ``median_error`` the view's median error there (fraction of the person's size) and
    ``swapped`` how many of those frames are left/right swaps."""

    person: int
    view: int
    ranges: tuple[tuple[int, int], ...]
    frames: int
    median_error: float
    swapped: int = 0


@dataclass
class Consistency:
    """The check of every person, frame and view.

    Attributes:
        status: :class:`ViewStatus` per (T, P, V), uint8.
        error: the view's error (T, P, V), a fraction of the person's size; NaN where not
            compared.
        size: the person's size in each view (T, P, V), pixels; NaN where unknown.
        compared: (T, P) frames in which at least 2 views were compared.
        contested: (T, P) compared frames in which a view disagrees.
        failed: (P,) people contested in more than ``most_frames`` of their compared frames.
        config: the settings used.
        swapped: (T, P, V) disagreeing views whose left/right-mirrored 2D agrees; all False
            when no mirror permutation was given.
    """

    status: np.ndarray
    error: np.ndarray
    size: np.ndarray
    compared: np.ndarray
    contested: np.ndarray
    failed: np.ndarray
    config: ConsistencyConfig
    swapped: np.ndarray | None = None

    def disagreements(self, frames: np.ndarray | None = None) -> list[Disagreement]:
        """Each (person, view) with disagreeing frames, most frames first."""
        T = self.status.shape[0]
        frames = np.arange(T) if frames is None else np.asarray(frames)
        out = []
        for p, v in zip(*np.nonzero((self.status == ViewStatus.DISAGREES).any(0)), strict=True):
            mask = self.status[:, p, v] == ViewStatus.DISAGREES
            err = self.error[mask, p, v]
            med = float(np.median(err[np.isfinite(err)])) if np.isfinite(err).any() else np.nan
            ranges = tuple(frame_ranges(frames, mask))
            swaps = 0 if self.swapped is None else int(self.swapped[:, p, v].sum())
            out.append(Disagreement(int(p), int(v), ranges, int(mask.sum()), med, swaps))
        return sorted(out, key=lambda d: (-d.frames, d.person, d.view))

    @property
    def exit_code(self) -> int:
        """0, or :data:`EXIT_VIEWS_DISAGREE` when some person failed."""
        return EXIT_VIEWS_DISAGREE if self.failed.any() else 0


def person_2d(
    keypoints: np.ndarray, scores: np.ndarray, membership: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each track's 2D in each view, from the run's input and the tracks' membership.

    Args:
        keypoints: the run's 2D input (T, V, N, J, 2) pixels; scores (T, V, N, J).
        membership: (T, P, V) index on the N axis, -1 where none
            (:attr:`rmpl.io.poses.Poses3D.membership`).

    Returns:
        keypoints (T, P, V, J, 2), NaN where none; scores (T, P, V, J), 0 there.
    """
    T, V, N, J, _ = keypoints.shape
    P = membership.shape[1]
    t = np.arange(T)[:, None, None]
    v = np.arange(V)[None, None, :]
    m = np.clip(membership, 0, max(N - 1, 0))
    kp = keypoints[t, v, m] if N else np.full((T, P, V, J, 2), np.nan)
    sc = scores[t, v, m] if N else np.zeros((T, P, V, J))
    none = membership < 0
    return np.where(none[..., None, None], np.nan, kp), np.where(none[..., None], 0.0, sc)


def _sizes(
    points: np.ndarray, keypoints: np.ndarray, rig: Rig, heights: np.ndarray | None
) -> np.ndarray:
    """The person's upright height in pixels at its centroid's depth, (T, P, V); where the
    centroid is behind the camera, the larger side of the 2D's bounding box."""
    P = points.shape[1]
    H = np.full(P, NOMINAL_HEIGHT)
    if heights is not None:
        H = np.where(np.isfinite(heights), heights, NOMINAL_HEIGHT)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # absent people: all-NaN means
        centre = np.nanmean(points, axis=-2)  # (T, P, 3)
    depth = np.einsum("vij,tpj->tpvi", rig.R, centre)[..., 2] + rig.t[:, 2]  # (T, P, V)
    f = 0.5 * (rig.K[:, 0, 0] + rig.K[:, 1, 1])  # (V,)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # views without 2D: all-NaN
        box = np.nanmax(keypoints, axis=-2) - np.nanmin(keypoints, axis=-2)  # (T, P, V, 2)
        box = np.max(box, axis=-1)
        return np.where(depth > 0, f * H[None, :, None] / depth, box)


def _in_image(points: np.ndarray, rig: Rig) -> np.ndarray:
    """(T, P, V): the person's centroid projects inside the image (known size), or in
    front of the camera (unknown size)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        centre = np.nanmean(points, axis=-2)  # (T, P, 3)
    uv = rig.project(centre[..., None, :])[..., 0, :]  # (T, P, V, 2), NaN behind
    size = rig.sizes  # (V, 2), NaN unknown
    inside = (uv >= 0) & (uv <= size)
    return np.where(np.isnan(size), np.isfinite(uv), inside).all(-1)


class _Errors:
    """Reprojection errors of reference 3D against each view's 2D, as size fractions."""

    def __init__(self, kp, sc, rig, size, min_joints):
        self.kp, self.sc, self.rig, self.size, self.min_joints = kp, sc, rig, size, min_joints
        self.valid = np.isfinite(kp).all(-1) & (sc > 0)  # (T, P, V, J)

    def triangulate(self, views: np.ndarray) -> np.ndarray:
        """3D (T, P, J, 3) from the views ``views`` (T, P, V) bool of each person."""
        w = np.where(views[..., None] & self.valid, self.sc, 0.0)
        return triangulate_points(self.kp, w, self.rig)

    def __call__(self, reference: np.ndarray) -> np.ndarray:
        """(T, P, V): median joint distance / size; NaN with fewer than min_joints. A joint
        triangulated behind the camera is infinitely far from the view's 2D."""
        proj = self.rig.project(reference)  # (T, P, V, J, 2)
        d = np.linalg.norm(proj - self.kp, axis=-1)
        known = np.isfinite(reference).all(-1)[:, :, None, :]  # (T, P, 1, J)
        d = np.where(self.valid & known & np.isnan(d), np.inf, d)  # behind the camera
        d = np.where(self.valid & known, d, np.nan)
        enough = (~np.isnan(d)).sum(-1) >= self.min_joints
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(d, axis=-1)
        return np.where(enough, med / self.size, np.nan)


def _consensus(err: _Errors, has2d: np.ndarray, thr: float, bar) -> tuple[np.ndarray, np.ndarray]:
    """The set of mutually agreeing views per person and frame (T, P, V) bool (the lowest
    truncated cost of a consistent pair), and (T, P) whether any pair could be compared."""
    T, P, V = has2d.shape
    best = np.full((T, P), np.inf)
    consensus = np.zeros((T, P, V), bool)
    comparable = np.zeros((T, P), bool)
    for a, b in itertools.combinations(range(V), 2):
        bar.update()
        pair = np.zeros(V, bool)
        pair[[a, b]] = True
        E = err(err.triangulate(np.broadcast_to(pair, has2d.shape) & has2d))
        comparable |= ~np.isnan(E[..., a]) & ~np.isnan(E[..., b])
        ok = (E[..., a] <= thr) & (E[..., b] <= thr)
        inliers = (E <= thr) & ok[..., None]
        capped = np.where(has2d, np.minimum(np.nan_to_num(E, nan=thr), thr), 0.0)
        cost = np.where(ok, capped.sum(-1), np.inf)  # views not compared cost the cap
        better = cost < best
        best = np.where(better, cost, best)
        consensus = np.where(better[..., None], inliers, consensus)
    return consensus, comparable


def check_views(
    points: np.ndarray,
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    heights: np.ndarray | None = None,
    config: ConsistencyConfig | None = None,
    mirror: np.ndarray | None = None,
    skeleton: str | None = None,
    points_skeleton: str | None = None,
) -> Consistency:
    """Check every person's 3D against each view's 2D (see the module docstring).

    Args:
        points: the run's 3D (T, P, J, 3) metres, NaN = missing (only its centroid is
            used: the person's depth and whether it is in a view).
        keypoints: each person's 2D per view (T, P, V, J, 2) pixels, NaN where none
            (:func:`person_2d`); scores (T, P, V, J), 0 where none.
        rig: the V cameras.
        heights: (P,) metres, NaN unknown (then 1.70 m); sets each person's size.
        config: thresholds.
        mirror: (J,) the joint permutation exchanging left and right of the 2D's joint set
            (:meth:`rmpl.skeleton.Skeleton.flip_permutation`), to tell left/right swaps;
            None skips that.
        skeleton, points_skeleton: the joint sets of ``keypoints`` and ``points``; None:
            COCO-17 for 17 joints, HALPE-26 for 26. Only their COCO-17 joints are used (see
            the module docstring).

    Returns:
        :class:`Consistency`.
    """
    cfg = config or ConsistencyConfig()
    use = coco17_joints(keypoints.shape[-2], skeleton)
    if mirror is not None:
        where = {j: i for i, j in enumerate(use)}
        mirror = np.array([where[int(np.asarray(mirror)[j])] for j in use])
    keypoints, scores = keypoints[..., use, :], scores[..., use]
    points = points[..., coco17_joints(points.shape[-2], points_skeleton), :]
    present = ~np.isnan(points).all((-1, -2))  # (T, P)
    size = _sizes(points, keypoints, rig, heights)
    T, P, V = size.shape
    status = np.full((T, P, V), int(ViewStatus.ABSENT), np.uint8)
    error = np.full((T, P, V), np.nan)
    swapped = np.zeros((T, P, V), bool)
    # Only the person-frames with 3D are checked; the others are absent in every view.
    rows = np.nonzero(present)
    sub = _check_rows(
        points[rows][None], keypoints[rows][None], scores[rows][None], rig,
        size[rows][None], cfg, mirror, progress=T * P >= PROGRESS_FROM,
    )  # fmt: skip
    status[rows], error[rows], swapped[rows] = (a[0] for a in sub)
    agrees = (status == ViewStatus.AGREES).sum(-1)
    disagrees = (status == ViewStatus.DISAGREES).sum(-1)
    compared = agrees + disagrees >= 2
    contested = compared & (disagrees >= 1)
    n_compared = compared.sum(0)
    failed = (n_compared > 0) & (contested.sum(0) > cfg.most_frames * n_compared)
    return Consistency(status, error, size, compared, contested, failed, cfg, swapped)


def _check_rows(points, keypoints, scores, rig, size, cfg, mirror, progress):
    """:func:`check_views`'s statuses (T, P, V), errors (T, P, V) and left/right swaps
    (T, P, V) of people with 3D in every frame (``points`` (T, P, J, 3) not all NaN),
    their sizes ``size`` (T, P, V) given."""
    from tqdm import tqdm

    thr = cfg.threshold
    err = _Errors(keypoints, scores, rig, size, cfg.min_joints)
    has2d = err.valid.any(-1)  # (T, P, V)
    V = has2d.shape[-1]
    # long recordings: a few seconds per 10,000 person-frames
    bar = tqdm(total=V * (V - 1) // 2 + V, desc="view check", unit="step", disable=not progress)
    consensus, comparable = _consensus(err, has2d, thr, bar)
    found = consensus.any(-1)  # (T, P)
    error = np.full(has2d.shape, np.nan)
    flipped = np.full(has2d.shape, np.nan)
    mirrored = None
    if mirror is not None:
        mirror = np.asarray(mirror)
        mirrored = _Errors(
            keypoints[..., mirror, :], scores[..., mirror], rig, size, cfg.min_joints
        )
    for v in range(V):
        bar.update()
        others = consensus.copy()
        others[..., v] = False
        everyone = has2d.copy()
        everyone[..., v] = False
        n, m = others.sum(-1, keepdims=True), everyone.sum(-1, keepdims=True)
        fallback = np.where(m >= 2, everyone, has2d)  # no consensus: all the (other) views
        ref = np.where(n >= 2, others, np.where(found[..., None], consensus, fallback))
        X = err.triangulate(ref)
        error[..., v] = err(X)[..., v]
        if mirrored is not None:
            flipped[..., v] = mirrored(X)[..., v]
    bar.close()
    error = np.where(has2d, error, np.nan)

    status = np.full(has2d.shape, int(ViewStatus.UNCHECKED), np.uint8)
    checked = np.isfinite(error)
    status[checked & (error <= thr)] = ViewStatus.AGREES
    status[checked & (error > thr)] = ViewStatus.DISAGREES
    # no two views agree: every view that could be compared disagrees (a view with too few
    # joints to compare stays unchecked)
    enough = err.valid.sum(-1) >= cfg.min_joints  # (T, P, V)
    status[has2d & enough & ~found[..., None] & comparable[..., None]] = ViewStatus.DISAGREES
    inside = _in_image(points, rig)
    status[~has2d & inside] = ViewStatus.MISSED
    status[~has2d & ~inside] = ViewStatus.OUT_OF_VIEW
    swapped = (status == ViewStatus.DISAGREES) & (flipped <= np.minimum(thr, 0.5 * error))
    return status, error, swapped


def frame_ranges(frames: np.ndarray, mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of consecutive True entries of ``mask`` as inclusive (first, last) frame numbers.

    >>> frame_ranges(np.arange(10, 20), np.array([0, 1, 1, 0, 1, 0, 0, 1, 1, 1], bool))
    [(11, 12), (14, 14), (17, 19)]
    """
    idx = np.flatnonzero(mask)
    if not len(idx):
        return []
    cuts = np.flatnonzero(np.diff(idx) > 1)
    starts = np.r_[idx[0], idx[cuts + 1]]
    ends = np.r_[idx[cuts], idx[-1]]
    return [(int(frames[a]), int(frames[b])) for a, b in zip(starts, ends, strict=True)]


def format_ranges(ranges, limit: int = 6) -> str:
    """``"3-40, 52, 60-61"``; after ``limit`` ranges, ``"... (+N more)"``.

    >>> format_ranges([(3, 40), (52, 52), (60, 61)])
    '3-40, 52, 60-61'
    """
    text = [f"{a}" if a == b else f"{a}-{b}" for a, b in ranges[:limit]]
    more = f" (+{len(ranges) - limit} more)" if len(ranges) > limit else ""
    return ", ".join(text) + more


def held_out_px(check: Consistency) -> np.ndarray:
    """(V,) each camera's median held-out error in pixels: its 2D against the person placed
    by the other cameras, over every compared person-frame; NaN where none was compared."""
    px = check.error * check.size  # (T, P, V)
    out = np.full(px.shape[-1], np.nan)
    for v in range(px.shape[-1]):
        e = px[..., v][np.isfinite(px[..., v])]
        if e.size:
            out[v] = float(np.median(e))
    return out


def moved_cameras(median_px: np.ndarray) -> np.ndarray:
    """(V,) bool: the worst camera, when its held-out median error exceeds both
    :data:`MOVED_PX` and :data:`MOVED_RATIO` times the others' median (three cameras or
    more, each measured)."""
    median_px = np.asarray(median_px, float)
    moved = np.zeros(len(median_px), bool)
    if len(median_px) < 3 or not np.isfinite(median_px).all():
        return moved
    worst = int(np.argmax(median_px))
    rest = float(np.median(np.delete(median_px, worst)))
    moved[worst] = median_px[worst] > MOVED_PX and median_px[worst] > MOVED_RATIO * rest
    return moved
