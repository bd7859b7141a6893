"""From 2D detections of several calibrated views to tracked, smoothed 3D skeletons.

Each stage is a function usable on its own:

1. :func:`associate_frames`: per frame, group the views' 2D people into 3D people by
   geometry (:mod:`rmpl.pipeline.association`); with one person per view this is the identity.
2. :func:`estimate`: lift (RMPL) or triangulate every associated person, all frames batched.
3. :func:`track_people`: identities over time (:mod:`rmpl.pipeline.tracking`).
4. :func:`smooth`: outlier removal, gap filling (flagged as interpolated) and a zero-phase
   Butterworth or a one-euro filter (:mod:`rmpl.pipeline.filters`).

:func:`run` chains them and returns a :class:`rmpl.io.poses.Poses3D`. It keeps, per track,
frame and view, which 2D person of the input the track used (``membership``, from each
frame's :attr:`Association.members <rmpl.pipeline.association.Association>` through the
tracker's index) and how many of that person's keypoints the estimator left out
(``views_excluded``), so that the 3D can be checked against each view's 2D afterwards
(:mod:`rmpl.pipeline.consistency`).

A lifter that reads the floor (:attr:`rmpl.Lifter.reads_floor`, or the temporal one's) is
given one: the user's, or by default one estimated once per run from the run's own people
(:func:`estimate_floor`: triangulated, then the lowest ankles); :func:`run_with_floor` also
returns the floor the lifter was given, for the report.

Shape glossary: ``T`` frames, ``V`` views, ``P`` people, ``N`` people in one frame,
``J`` joints.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.io.keypoints import FAR_MARGIN, drop_far_keypoints
from rmpl.io.poses import JointSource, Poses3D
from rmpl.pipeline.association import Association, AssociationConfig, associate
from rmpl.pipeline.identity import IdentityConfig
from rmpl.skeleton import BY_COUNT

__all__ = [
    "RunConfig",
    "associate_frames",
    "estimate",
    "estimate_floor",
    "track_people",
    "smooth",
    "run",
    "run_with_floor",
]

log = logging.getLogger(__name__)

METHODS = ("rmpl", "triangulate", "robust")
FILTERS = ("butterworth", "one-euro", "none")
#: ``run(floor=ESTIMATE)``: the floor estimated from the run's own multi-view people.
ESTIMATE = "estimate"


@dataclass(frozen=True)
class RunConfig:
    """Settings of :func:`run`.

    Attributes:
        method: "rmpl" (learned lifting), "triangulate" (weighted DLT) or "robust".
        model: shipped model name or checkpoint folder, for "rmpl".
        up: world up axis (3,), or None to estimate it from the cameras.
        filter: "butterworth" (zero-phase, Pose2Sim's default), "one-euro" or "none".
        cutoff: Butterworth cut-off frequency, Hz (Pose2Sim: 6 Hz).
        order: Butterworth order (the two-pass total; Pose2Sim: 4).
        one_euro_min_cutoff: one-euro minimum cut-off, Hz.
        one_euro_beta: one-euro speed coefficient (per m/s).
        hampel: remove outliers with a Hampel filter (window 7) before filling gaps.
        hampel_min_deviation: a point is an outlier only if it is also this far (metres)
            from the window's median, so smooth motion with tiny noise keeps its points.
        max_gap: fill gaps up to this many frames (Pose2Sim: 20); 0 disables.
        min_score: triangulation ignores keypoints below this confidence (None: 0 for
            "triangulate", 0.3 for "robust", as Pose2Sim).
        max_error: "robust": reprojection error threshold, pixels (Pose2Sim: 15).
        swap_check: "robust": test left/right swaps per view.
        track_distance: gate of the tracker, metres of mean joint distance.
        max_missed: frames a track survives without a match.
        min_track_frames: drop tracks present in fewer frames than this (ghosts from a
            one-frame false association); 1 keeps every track.
        association: cross-view association thresholds.
        identity: the rules that join the tracker's fragments into one track per person
            (:mod:`rmpl.pipeline.identity`; its ``min_frames`` is ``min_track_frames``).
    """

    method: str = "rmpl"
    model: str = "default"
    up: tuple[float, float, float] | None = None
    filter: str = "butterworth"
    cutoff: float = 6.0
    order: int = 4
    one_euro_min_cutoff: float = 1.0
    one_euro_beta: float = 1.0
    hampel: bool = True
    hampel_min_deviation: float = 0.03
    max_gap: int = 20
    min_score: float | None = None
    max_error: float = 15.0
    swap_check: bool = True
    track_distance: float = 0.5
    max_missed: int = 10
    min_track_frames: int = 3
    association: AssociationConfig = field(default_factory=AssociationConfig)
    identity: IdentityConfig = field(default_factory=IdentityConfig)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        if self.filter not in FILTERS:
            raise ValueError(f"filter must be one of {FILTERS}, got {self.filter!r}")
        if self.min_track_frames < 1:
            raise ValueError(f"min_track_frames must be >= 1, got {self.min_track_frames}")
        _check_range("cutoff", self.cutoff, 0.0, None, "a frequency > 0 Hz")
        _check_range("max_gap", self.max_gap, 0, None, "a number of frames >= 0", closed=True)
        if self.min_score is not None:
            _check_range("min_score", self.min_score, 0, 1, "a confidence in [0, 1]", closed=True)
        _check_range("max_error", self.max_error, 0.0, None, "a reprojection error > 0 pixels")


def _check_range(name, value, lo, hi, expected: str, closed: bool = False) -> None:
    """``lo < value`` (``<=`` when closed) and ``value <= hi``; NaN is out of range."""
    ok = value >= lo if closed else value > lo
    if not (ok and (hi is None or value <= hi)):
        raise ValueError(f"{name} must be {expected}, got {value}")


def associate_frames(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    config: AssociationConfig | None = None,
    progress: bool = False,
) -> list[Association]:
    """Per-frame 3D people from per-view 2D people.

    Args:
        keypoints: (T, V, P, J, 2) pixels, people not associated across views.
        scores: (T, V, P, J).

    Returns:
        One :class:`Association` per frame: keypoints (N, V, J, 2), scores (N, V, J).
    """
    from tqdm import tqdm

    T, V, P = keypoints.shape[:3]
    present = (scores > 0).any(-1)  # (T, V, P)
    if P == 1:  # one person per view: nothing to associate
        out = []
        for t in range(T):
            seen = present[t, :, 0]
            members = np.where(seen, 0, -1)[None]
            if seen.sum() == 0:
                out.append(
                    Association(
                        keypoints[t, :, 0][None][:0], scores[t, :, 0][None][:0], members[:0]
                    )
                )
            else:
                out.append(Association(keypoints[t, :, 0][None], scores[t, :, 0][None], members))
        return out
    frames = range(T)
    if progress:
        frames = tqdm(frames, desc="associate", unit="frame")
    return [
        associate(
            [keypoints[t, v][present[t, v]] for v in range(V)],
            [scores[t, v][present[t, v]] for v in range(V)],
            rig,
            config,
        )
        for t in frames
    ]


def input_skeleton(num_joints: int, joints: str | None = None) -> str:
    """The name of a 2D input's joint set: ``joints``, else COCO-17 for 17 joints and
    HALPE-26 for 26 (the two sets ``rmpl run`` reads 2D in; both begin with COCO-17).

    Raises:
        InputError: ``joints`` unknown or of another joint count, or None with a count
            other than 17 or 26.
    """
    from rmpl.skeleton import SKELETONS

    name = joints if joints is not None else BY_COUNT.get(num_joints)
    if name not in SKELETONS or SKELETONS[name].num_joints != num_joints:
        raise InputError(
            None, "keypoints", "17 (COCO-17) or 26 (HALPE-26) joints, or a named joint set of "
            "that many", f"{num_joints} joints ({joints or 'unnamed'})",
        )  # fmt: skip
    if name not in BY_COUNT.values():  # later stages index COCO-17 joints by position
        raise InputError(
            None, "joints", "coco17 or halpe26 (rmpl.skeleton.embed places other sets' "
            "joints, as rmpl.load_keypoints does)", name,
        )  # fmt: skip
    return name


_COCO_JOINTS = 17  # COCO-17 is the first 17 joints of both output sets


def _estimator(
    config: RunConfig, used: bool = False, joints: str | None = None, floor=None, lifter=None
):
    """``fn(kp, sc, rig) -> (points, num_views)``, or with ``used`` ``(points, num_views,
    views used (N, V, J) bool)``, J the output's joints.

    ``joints`` names the 2D's joint set (None: by its joint count, :func:`input_skeleton`).
    ``floor`` (:class:`rmpl.geometry.floor.Floor`) goes to a lifter that reads it.
    ``lifter``: the :class:`rmpl.Lifter` of ``config.model`` when already loaded.
    The function's attribute ``skeleton`` names the output's joint set when known before
    the first call: the lifter's own (:attr:`rmpl.Lifter.skeleton`); triangulation keeps
    the 2D's (``fn.skeleton`` is then ``joints``, possibly None).
    """
    from rmpl.geometry.triangulate import triangulate, triangulate_robust
    from rmpl.skeleton import SKELETONS, to_model_joints

    def out(points, num_views, mask):
        return (points, num_views, mask) if used else (points, num_views)

    if config.method == "rmpl":
        from rmpl.inference import Lifter

        lifter = lifter or Lifter.from_pretrained(config.model)
        up = None if config.up is None else np.asarray(config.up, float)
        skeleton = lifter.skeleton

        def lift(kp, sc, rig):
            name = input_skeleton(kp.shape[-2], joints)
            r = lifter.lift(kp, sc, rig, up=up, joints=name, floor=floor)
            if name != skeleton.name:  # the views used, in the model's joints
                kp, sc = to_model_joints(kp, sc, skeleton, name)
            return out(r.points, r.num_views, np.isfinite(kp).all(-1) & (sc > 0))

        lift.skeleton = skeleton.name
        return lift

    def triangulated(r):
        return out(r.points, r.num_views, r.views)

    if config.method == "robust":
        min_score = 0.3 if config.min_score is None else config.min_score

        def robust(kp, sc, rig):
            name = joints or BY_COUNT.get(kp.shape[-2])  # left/right swaps need the names
            pairs = SKELETONS[name].flip_pairs if name in SKELETONS else None
            kwargs = {"min_score": min_score, "max_error": config.max_error}
            kwargs["swap_pairs"] = pairs if config.swap_check else None
            return triangulated(triangulate_robust(kp, sc, rig, **kwargs))

        robust.skeleton = joints
        return robust
    min_score = config.min_score or 0.0

    def dlt(kp, sc, rig):
        return triangulated(triangulate(kp, sc, rig, min_score=min_score))

    dlt.skeleton = joints
    return dlt


def estimate(
    people: list[Association],
    rig: Rig,
    config: RunConfig,
    chunk: int = 2048,
    progress: bool = False,
    fn=None,
    used: bool = False,
    joints: str | None = None,
    floor=None,
) -> tuple[list[np.ndarray], ...]:
    """3D joints of every associated person, batched over frames.

    ``fn(kp, sc, rig) -> (points, num_views)`` replaces the estimator ``config`` names
    (with ``used``, ``fn`` must also return the views used, (N, V, J) bool). ``joints``
    names the 2D's joint set (None: by its joint count); the lifter answers in its own
    (:attr:`rmpl.Lifter.skeleton`). ``floor`` (:class:`rmpl.geometry.floor.Floor`) goes to
    a lifter that reads it (without ``fn``).

    Returns:
        Per frame: points (N, J, 3) metres and the number of views per joint (N, J); with
        ``used`` also which views each joint used (N, V, J) bool. J is the output's.
    """
    from tqdm import tqdm

    fn = fn or _estimator(config, used=used, joints=joints, floor=floor)
    counts = [len(a) for a in people]
    if sum(counts) == 0:
        J = people[0].keypoints.shape[-2] if people else 17
        J = _num_joints(getattr(fn, "skeleton", None), J)
        V = people[0].keypoints.shape[1] if people else 0
        empty = [np.zeros((0, J, 3)) for _ in people], [np.zeros((0, J), int) for _ in people]
        return (*empty, [np.zeros((0, V, J), bool) for _ in people]) if used else empty
    kp = np.concatenate([a.keypoints for a in people if len(a)])
    sc = np.concatenate([a.scores for a in people if len(a)])
    starts = range(0, len(kp), chunk)
    if progress and len(kp) > chunk:
        starts = tqdm(starts, desc=config.method, unit="chunk")
    answers = [fn(kp[s : s + chunk], sc[s : s + chunk], rig) for s in starts]
    pts = np.concatenate([r[0] for r in answers]).astype(float)  # (all people, J, 3)
    nv = np.concatenate([r[1] for r in answers]).astype(int)
    split = np.cumsum(counts)[:-1]
    if used:
        mask = np.concatenate([r[2] for r in answers]).astype(bool)  # (all people, V, J)
        return np.split(pts, split), np.split(nv, split), np.split(mask, split)
    return np.split(pts, split), np.split(nv, split)


def estimate_floor(people: list[Association], rig: Rig, up: np.ndarray | None = None):
    """The floor under a run's own people: each associated person of each frame
    triangulated (DLT, the joints two or more views see), then
    :func:`rmpl.pipeline.depth_cues.floor_from_poses` (the lowest ankle of every pose that
    may touch the floor).

    Args:
        people: per frame, the :class:`Association` of :func:`associate_frames`; their
            first 17 joints are COCO-17's (COCO-17 or HALPE-26 2D).
        up: the world up direction (3,); None: :func:`rmpl.inference.estimate_up` of the rig.

    Returns:
        The :class:`rmpl.geometry.floor.Floor`; its ``source`` says how it was found.

    Raises:
        InputError: fewer than 10 usable poses (e.g. one camera, or few frames).
    """
    from dataclasses import replace

    from rmpl.geometry.triangulate import triangulate
    from rmpl.inference import estimate_up
    from rmpl.pipeline.depth_cues import floor_from_poses

    found = [a for a in people if len(a)]
    if not found:
        raise InputError(None, "floor", "people seen by 2+ cameras to estimate it", "none")
    if found[0].keypoints.shape[-2] < _COCO_JOINTS:
        raise InputError(None, "floor", "2D whose first 17 joints are COCO-17's to estimate it",
                         f"{found[0].keypoints.shape[-2]} joints")  # fmt: skip
    kp = np.concatenate([a.keypoints[..., :_COCO_JOINTS, :] for a in found])  # (N, V, 17, 2)
    sc = np.concatenate([a.scores[..., :_COCO_JOINTS] for a in found])
    points = triangulate(kp, sc, rig).points  # (N, 17, 3), NaN where < 2 views
    floor = floor_from_poses(points, estimate_up(rig) if up is None else up)
    return replace(floor, source=f"{floor.source}; triangulated from the run's {len(rig)} cameras")


def _run_floor(floor, people: list[Association], rig: Rig, cfg: RunConfig, reads: bool):
    """The floor the lifter is given: None when it does not read the floor (or ``floor`` is
    None); the checked ``floor``; or with :data:`ESTIMATE`, :func:`estimate_floor` (None,
    with a log line, when too few poses allow it). Says which in one log line (none for
    triangulation, which has no use for a floor)."""
    if cfg.method != "rmpl":
        return None
    if not reads:
        if floor is None or isinstance(floor, str):
            log.info("floor: none (model %s does not read the floor)", cfg.model)
        else:
            log.warning("the floor given is not used: model %s does not read the floor "
                        "(floor26 does)", cfg.model)  # fmt: skip
        return None
    if floor is None:
        log.info("floor: none given (the lifter goes without)")
        return None
    if isinstance(floor, str):  # ESTIMATE (checked by _checked_floor_spec)
        up = None if cfg.up is None else np.asarray(cfg.up, float)
        try:
            floor = estimate_floor(people, rig, up)
        except InputError as e:
            log.info(
                "floor: not estimated (%s; got %s): the lifter goes without", e.expected, e.got
            )
            return None
    log.info("floor given to the lifter: %s", floor.describe())
    return floor


def _checked_floor_spec(floor, rig: Rig):
    """``run``'s ``floor``: :data:`ESTIMATE`, None, or a floor checked against the rig."""
    if floor is None or (isinstance(floor, str) and floor == ESTIMATE):
        return floor
    if isinstance(floor, str):
        raise InputError(None, "floor", f"an rmpl.geometry.floor.Floor, {ESTIMATE!r} or None",
                         repr(floor))  # fmt: skip
    from rmpl.inference import checked_floor

    return checked_floor(floor, rig)


def _num_joints(skeleton: str | None, default: int) -> int:
    from rmpl.skeleton import SKELETONS

    return SKELETONS[skeleton].num_joints if skeleton in SKELETONS else default


def track_people(
    points: list[np.ndarray], num_views: list[np.ndarray], config: RunConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Identities over time.

    Returns:
        tracks (T, P, J, 3), views (T, P, J) (0 where absent), ids (P,).
    """
    return _track(points, num_views, config)[:3]


def _track(points: list[np.ndarray], num_views: list[np.ndarray], config: RunConfig, **seen):
    """:func:`track_people` plus the index (T, P) of each track's person per frame and the
    identity record (``seen``: :func:`identity_index`'s ``fps``, ``people``, ``rig``)."""
    T = len(points)
    J = points[0].shape[-2] if T else 17
    record = None
    if all(len(p) <= 1 for p in points):  # a single person: no identities to keep
        index, ids = np.array([[0 if len(p) else -1] for p in points]).reshape(T, 1), [0]
    else:
        index, ids, record = identity_index(points, config, **seen)
    tracks = np.full((T, index.shape[1], J, 3), np.nan)
    views = np.zeros(tracks.shape[:3], int)
    for t, p in zip(*np.nonzero(index >= 0), strict=True):
        tracks[t, p], views[t, p] = points[t][index[t, p]], num_views[t][index[t, p]]
    return tracks, views, np.asarray(ids), index, record


def view_records(
    people: list[Association],
    index: np.ndarray,
    present: np.ndarray,
    num_views: list[np.ndarray] | None = None,
    used: list[np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Which 2D person of each view every track used, and how many of its keypoints were
    left out.

    Args:
        people: per frame, the :class:`Association` of :func:`associate_frames`.
        index: (T, P) each track's person in each frame, -1 where absent.
        present: (T, V, N_in) the 2D input's people with a keypoint (score > 0), as
            :func:`associate_frames` saw them: its per-view lists hold only these.
        num_views: per frame, views per joint (N, J) of the estimator; with ``used``.
        used: per frame, the views each joint used (N, V, J) bool; None: nothing left out.
            J is the estimator's (the lifter's joint set may differ from the 2D's: the
            joints both begin with, COCO-17, are compared).

    Returns:
        membership (T, P, V): the index on the 2D input's people axis, -1 where none;
        excluded (T, P, V): keypoints with confidence > 0 of that person the estimator did
        not use for a joint it estimated.
    """
    T, P = index.shape
    V = present.shape[1]
    membership = np.full((T, P, V), -1, np.int64)
    excluded = np.zeros((T, P, V), np.int32)
    for t, p in zip(*np.nonzero(index >= 0), strict=True):
        n = index[t, p]
        m = people[t].members[n]  # (V,) into each view's list of present people
        for v in np.flatnonzero(m >= 0):
            membership[t, p, v] = np.flatnonzero(present[t, v])[m[v]]
        if used is not None:
            a = people[t]
            available = np.isfinite(a.keypoints[n]).all(-1) & (a.scores[n] > 0)  # (V, J_2d)
            estimated = num_views[t][n] > 0  # (J,)
            J = min(available.shape[-1], len(estimated))  # the joints both sets share
            excluded[t, p] = (available[:, :J] & ~used[t][n][:, :J] & estimated[:J]).sum(-1)
    return membership, excluded


def track_index(points: list[np.ndarray], config: RunConfig) -> tuple[np.ndarray, np.ndarray]:
    """Identities over time as indices: (T, P) the person of each track in each frame (-1
    where absent) and the track ids (P,): :func:`identity_index` without the ghost rule."""
    return identity_index(points, config)[:2]


def identity_index(points: list[np.ndarray], config: RunConfig, fps=None, people=None, rig=None):
    """The tracker's fragments (:func:`rmpl.pipeline.tracking.track_indices`) joined into
    identities by :func:`rmpl.pipeline.identity.resolve` (duplicates, gaps, ``--people``;
    identities in fewer than ``min_track_frames`` frames dropped; with ``people``, the
    per-frame :class:`Association` list, and ``rig`` the ghost rule too).

    The tracker matches people on the COCO-17 joints, the first 17 of every joint set rmpl
    answers in (HALPE-26's head top, neck, mid-hip and feet do not vote), so that a COCO-17
    and a HALPE-26 answer are tracked alike.

    Returns:
        index (T, P), ids (P,) and the :class:`rmpl.pipeline.identity.Identities`.
    """
    from dataclasses import replace

    from rmpl.pipeline.identity import resolve, view_counts
    from rmpl.pipeline.tracking import track_indices

    kwargs = {"max_distance": config.track_distance, "max_missed": config.max_missed}
    points = [p[:, :_COCO_JOINTS] for p in points]
    index = track_indices(points, **kwargs)
    views = cameras = None
    if people is not None and rig is not None:
        views, cameras = view_counts(people, points, rig)
    rules = replace(config.identity, min_frames=config.min_track_frames)
    found = resolve(points, index, rules, fps, views, cameras)
    log.info(
        "identities: %d tracks from the tracker's %d fragments (%d merged, %d dropped)",
        found.index.shape[1], found.num_fragments, len(found.merges), len(found.drops),
    )  # fmt: skip
    return found.index, np.arange(found.index.shape[1], dtype=np.int64), found


def smooth(
    tracks: np.ndarray, fps: float | None, config: RunConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Outliers, gaps and jitter.

    Returns:
        smoothed (T, P, J, 3) and interpolated (T, P, J) bool: joints filled by the gap
        filler (they were missing before).
    """
    from rmpl.pipeline import filters as temporal

    x = tracks
    if config.hampel and len(x) >= 7:
        x = temporal.hampel(x, window=7, min_deviation=config.hampel_min_deviation)
    interpolated = np.zeros(x.shape[:-1], bool)
    if config.max_gap > 0:
        x, interpolated = temporal.fill_gaps(x, max_gap=config.max_gap)
    if config.filter != "none" and fps is None:
        log.warning("no frame rate known (give --fps): skipping the %s filter", config.filter)
    elif config.filter == "butterworth" and fps is not None:
        check_cutoff(config.cutoff, fps)
        x = temporal.butterworth(x, fps, cutoff=config.cutoff, order=config.order)
    elif config.filter == "one-euro" and fps is not None:
        x = temporal.one_euro(
            x, fps, min_cutoff=config.one_euro_min_cutoff, beta=config.one_euro_beta
        )
    return x, interpolated & np.isfinite(x).all(-1)


def _is_temporal(cfg: RunConfig) -> bool:
    from rmpl.inference_temporal import is_temporal_checkpoint

    return cfg.method == "rmpl" and is_temporal_checkpoint(cfg.model)


def lift_people(
    people: list[Association],
    rig: Rig,
    fps: float | None,
    cfg: RunConfig,
    joints: str | None = None,
    floor=None,
):
    """Track the associated people with per-frame estimates, then lift each track with the
    temporal model ``cfg.model``.

    Args:
        joints: the 2D's joint set (None: by its joint count, :func:`input_skeleton`).
        floor: the floor (:class:`rmpl.geometry.floor.Floor`) for a model that reads it,
            :data:`ESTIMATE` (:func:`estimate_floor`, when the model reads it) or None.

    Returns:
        tracks (T, P, J, 3), uncertainty (T, P, J) (the 50% error radius, metres), views
        (T, P, J), ids (P,) and interpolated (T, P, J): frames the model filled, where the
        track had no 2D. J is the model's (:attr:`TemporalLifter.skeleton
        <rmpl.inference_temporal.TemporalLifter.skeleton>`).
    """
    floor = _checked_floor_spec(floor, rig)
    return _lift_people(people, rig, fps, cfg, joints, floor)[:5]


def _lift_people(
    people, rig: Rig, fps: float | None, cfg: RunConfig, joints: str | None, floor=None
):
    """:func:`lift_people` plus the index (T, P) of each track's person per frame, the
    model's joint set, the floor it was given (``floor`` checked by
    :func:`_checked_floor_spec`) and the identity record (None with one person)."""
    from rmpl.inference import Lifter
    from rmpl.inference_temporal import TemporalLifter
    from rmpl.pipeline.tracklift import lift_tracks, tracks_2d

    if fps is None:
        raise InputError(None, "--fps", "a frame rate for the temporal model", "none known")
    lifter = TemporalLifter.from_pretrained(cfg.model)
    frame = Lifter(lifter.model.frame_model)
    up = None if cfg.up is None else np.asarray(cfg.up, float)
    floor = _run_floor(floor, people, rig, cfg, lifter.reads_floor)

    def fn(kp, sc, r):
        name = input_skeleton(kp.shape[-2], joints)
        x = frame.lift(kp, sc, r, up=up, joints=name, floor=floor)
        return x.points, x.num_views

    log.info(
        "the temporal model lifts whole tracks with its own assembly and filters "
        "(%s); --filter and --cutoff do not apply", lifter.assemble,
    )  # fmt: skip
    pts, _ = estimate(people, rig, cfg, fn=fn)
    J = lifter.num_joints
    name = lifter.skeleton.name
    if not any(len(p) for p in pts):  # nobody anywhere: an empty result (refused upstream)
        T = len(pts)
        empty = np.zeros((T, 0, J))
        index = np.zeros((T, 0), int)
        return (
            np.zeros((T, 0, J, 3)), empty, empty.astype(int), np.zeros(0, int), empty > 0, index,
            name, floor, None,
        )  # fmt: skip
    record = None
    if all(len(p) <= 1 for p in pts):  # a single person: no identities to keep
        index, ids = np.array([[0 if len(p) else -1] for p in pts]), np.array([0])
    else:
        index, ids, record = identity_index(pts, cfg, fps, people, rig)
    kp, sc = tracks_2d(people, index)
    named = input_skeleton(kp.shape[-2], joints)
    tracks, radius, views = lift_tracks(
        kp, sc, rig, lifter, fps, cfg.max_gap, up, named, floor=floor
    )
    filled = np.broadcast_to(~(sc > 0).any((-1, -2))[..., None], views.shape)
    interpolated = filled & np.isfinite(tracks).all(-1)
    return tracks, radius, views, ids, interpolated, index, name, floor, record


def check_cutoff(cutoff: float, fps: float) -> None:
    """A Butterworth cut-off must be below the Nyquist frequency ``fps / 2``."""
    if not cutoff < fps / 2:
        raise InputError(
            None,
            "--cutoff",
            f"a Butterworth cut-off below the Nyquist frequency fps / 2 = {fps / 2:g} Hz "
            f"(at {fps:g} frames/s), or --filter none",
            f"{cutoff:g} Hz",
        )


def check_run_cutoff(cfg: RunConfig, fps: float | None, temporal: bool = True) -> None:
    """:func:`check_cutoff` for a run that will apply the Butterworth filter: ``temporal``
    smoothing, a known ``fps``, and not a temporal model (its tracks are not filtered)."""
    if temporal and cfg.filter == "butterworth" and fps is not None and not _is_temporal(cfg):
        check_cutoff(cfg.cutoff, fps)


def drop_far(keypoints: np.ndarray, scores: np.ndarray, rig: Rig):
    """Keypoints (T, V, P, J, 2) far outside their image become missing, with a warning."""
    kp, sc, far = drop_far_keypoints(keypoints, scores, rig.sizes, view_axis=-4)
    if far:
        log.warning(
            "%d of %d keypoints (%.2g%%) lie more than %g image size beyond their image: "
            "treated as missing", far, int((scores > 0).sum()),
            100 * far / max(1, int((scores > 0).sum())), FAR_MARGIN,
        )  # fmt: skip
    return kp, sc


def run(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    frames: np.ndarray | None = None,
    fps: float | None = None,
    config: RunConfig | None = None,
    temporal: bool = True,
    progress: bool = True,
    joints: str | None = None,
    floor=ESTIMATE,
) -> Poses3D:
    """The whole chain on 2D input (T, V, P, J, 2) + scores (T, V, P, J).

    The answer's joint set (``Poses3D.skeleton``) is the lifter's own with "rmpl" (COCO-17,
    or HALPE-26: COCO-17 then head top, neck, mid-hip and six foot points), whatever the
    2D's; triangulation keeps the 2D's.

    Keypoints more than one image size beyond their image (cameras with a known size) are
    treated as missing and counted in a warning; a Butterworth cut-off at or above the
    Nyquist frequency is refused (InputError).

    Args:
        temporal: apply :func:`smooth` (outliers, gaps, filter); False keeps raw estimates.
        joints: the 2D's joint set (a name in :data:`rmpl.skeleton.SKELETONS`); None: by
            its joint count, COCO-17 for 17 and HALPE-26 for 26.
        floor: for a lifter that reads the floor (per frame :attr:`rmpl.Lifter.reads_floor`,
            whole tracks :attr:`TemporalLifter.reads_floor
            <rmpl.inference_temporal.TemporalLifter.reads_floor>`): an
            :class:`rmpl.geometry.floor.Floor` (checked against the cameras), :data:`ESTIMATE`
            (``"estimate"``, the default: :func:`estimate_floor` on the run's people, once;
            with too few usable poses, none, said in the log) or None (no floor). Other
            lifters and triangulation are given none, and nothing is estimated for them.

    Returns:
        :class:`Poses3D` with per-joint source flags and view counts, and per view the 2D
        person each track used (``membership``) and the keypoints left out
        (``views_excluded``). :func:`run_with_floor` also returns the floor used.

    Raises:
        InputError: a ``floor`` that is not a plane below the cameras, nor "estimate" or
            None; a Butterworth cut-off at or above the Nyquist frequency.
    """
    return run_with_floor(
        keypoints, scores, rig, frames, fps, config, temporal, progress, joints, floor
    )[0]


def run_with_floor(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    frames: np.ndarray | None = None,
    fps: float | None = None,
    config: RunConfig | None = None,
    temporal: bool = True,
    progress: bool = True,
    joints: str | None = None,
    floor=ESTIMATE,
):
    """:func:`run`, and the floor the lifter was given.

    Returns:
        ``(poses, floor)``: the :class:`Poses3D` and the :class:`rmpl.geometry.floor.Floor`
        the lifter read (the user's, or the estimated one), or None: no floor given, a
        lifter that does not read it, or none could be estimated.
    """
    cfg = config or RunConfig()
    floor = _checked_floor_spec(floor, rig)
    T = keypoints.shape[0]
    check_run_cutoff(cfg, fps, temporal)  # before the long part
    keypoints, scores = drop_far(keypoints, scores, rig)
    people = associate_frames(keypoints, scores, rig, cfg.association, progress)
    present = (scores > 0).any(-1)  # (T, V, N_in): the people associate_frames saw
    uncertainty = None
    if _is_temporal(cfg):  # whole tracks through the temporal lifter: it is the filter
        answer = _lift_people(people, rig, fps, cfg, joints, floor)
        tracks, uncertainty, views, ids, interpolated, index, skeleton, floor, record = answer
        membership, excluded = view_records(people, index, present)
    else:
        j2d = keypoints.shape[-2]
        answer = _per_frame(people, present, rig, fps, cfg, temporal, progress, joints, floor, j2d)
        tracks, views, ids, interpolated, membership, excluded, skeleton, floor, record = answer
    ok = np.isfinite(tracks).all(-1)
    source = JointSource.LIFTED if cfg.method == "rmpl" else JointSource.TRIANGULATED
    flags = np.where(interpolated, int(JointSource.INTERPOLATED), np.where(ok, int(source), 0))
    tracks[~ok] = np.nan
    poses = Poses3D(
        points=tracks,
        scores=None,
        flags=flags.astype(np.uint8),
        num_views=np.where(ok, views, 0).astype(np.int32),
        skeleton=skeleton,
        frames=np.arange(T) if frames is None else np.asarray(frames),
        fps=fps,
        person_ids=np.asarray(ids),
        uncertainty=uncertainty,
        membership=membership,
        views_excluded=np.where(ok.any(-1)[..., None], excluded, 0),
        camera_names=rig.names,
        identity=None if record is None else record.to_json(),
    )
    return poses, floor


def _per_frame(people, present, rig: Rig, fps, cfg: RunConfig, temporal, progress, joints,
               floor, j2d: int):  # fmt: skip
    """:func:`run_with_floor` with a per-frame estimator: estimate, track, then (``temporal``)
    smooth (``j2d``: the 2D's joint count). Returns tracks, views, ids, interpolated,
    membership, views excluded, the answer's joint set, the floor the estimator read and the
    identity record."""
    lifter = _lifter(cfg)
    reads = lifter is not None and lifter.reads_floor
    floor = _run_floor(floor, people, rig, cfg, reads)
    fn = _estimator(cfg, used=True, joints=joints, floor=floor, lifter=lifter)
    skeleton = fn.skeleton or input_skeleton(j2d, joints)
    pts, nv, used = estimate(people, rig, cfg, progress=progress, fn=fn, used=True)
    tracks, views, ids, index, record = _track(pts, nv, cfg, fps=fps, people=people, rig=rig)
    membership, excluded = view_records(people, index, present, nv, used)
    interpolated = np.zeros(tracks.shape[:-1], bool)
    if temporal:
        tracks, interpolated = smooth(tracks, fps, cfg)
    return tracks, views, ids, interpolated, membership, excluded, skeleton, floor, record


def _lifter(cfg: RunConfig):
    """The per-frame :class:`rmpl.Lifter` of ``cfg``, or None for triangulation."""
    if cfg.method != "rmpl":
        return None
    from rmpl.inference import Lifter

    return Lifter.from_pretrained(cfg.model)
