"""One calibrated camera: the lifter's people of one view, their depth from the cues.

One view gives rays, not where along them the person stands. The per-frame lifter
(:class:`rmpl.inference.Lifter`) still answers with a fair shape, but its distance from the
camera is off by about 20%. :mod:`rmpl.pipeline.depth_cues` chooses that distance from the
floor, body size and time (:class:`MonocularConfig` ``cues``); :func:`monocular_people`
lifts one view's people and applies the cues, :func:`lift_single_view` is ``rmpl run`` /
``rmpl lift`` with one camera.

A temporal model that reads the floor (:class:`rmpl.TemporalLifter`, ``reads_floor``) takes
the place of the cues: the per-frame model finds and follows the people, and each track is
lifted again as a whole, its floor given (:func:`temporal_tracks`); its error radius is the
temporal model's.

The uncertainty written to :attr:`rmpl.io.poses.Poses3D.uncertainty` is the 50% radius of
the depth error along each joint's ray (``0.674 sigma |X_j - C|``); it leaves out the
lifter's shape error.

Shape glossary: ``T`` frames, ``N`` people in one frame, ``P`` tracks, ``J`` joints.
Units: metres, seconds.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.geometry.floor import Floor, signed_distance
from rmpl.io.poses import JointSource, Poses3D
from rmpl.pipeline.depth_cues import (
    CONVENTION_FLOOR_SD,
    CUES,
    FLOOR_MODEL_LIFTER_SD,
    HIPS,
    RADIUS_50_1D,
    FrameCues,
    MonocularConfig,
    TrackDepth,
    floor_from_poses,
    floor_log_scale,
    frame_cues,
    may_touch_floor,
    per_frame_log_scale,
    scale_about,
    size_log_scale,
    stature_proxy,
    track_log_depth,
)
from rmpl.skeleton import BY_COUNT, COCO17

__all__ = [  # with the names of the cues (rmpl.pipeline.depth_cues)
    "CUES",
    "FLOOR_MODEL_LIFTER_SD",
    "FrameCues",
    "MonocularConfig",
    "MonocularResult",
    "TrackDepth",
    "floor_from_poses",
    "floor_log_scale",
    "frame_cues",
    "lift_single_view",
    "lift_stretch",
    "may_touch_floor",
    "monocular_people",
    "per_frame_log_scale",
    "size_log_scale",
    "stature_proxy",
    "temporal_tracks",
    "track_log_depth",
]

log = logging.getLogger(__name__)


@dataclass
class MonocularResult:
    """Poses of one view after the depth cues.

    Attributes:
        points: (T, P, J, 3) metres, J the lifter's joints. sigma: (T, P) log-depth
            standard deviation. views: (T, P, J) view counts. ids: (P,). tracks: per
            track, its :class:`TrackDepth` (time cue) or None. skeleton: the name of the
            joint set of ``points``. rows: (T, P) with the time cue, the row of the input
            people (``kp``) each track is in each frame, -1 none; else None.
    """

    points: np.ndarray
    sigma: np.ndarray
    views: np.ndarray
    ids: np.ndarray
    tracks: list
    skeleton: str = "coco17"
    rows: np.ndarray | None = None

    def radius(self, center: np.ndarray) -> np.ndarray:
        """The 50% radius of the depth error along each joint's ray, metres (T, P, J)."""
        dist = np.linalg.norm(self.points - center, axis=-1)
        return RADIUS_50_1D * self.sigma[..., None] * dist


def _up(rig: Rig, floor: Floor | None, up) -> np.ndarray:
    if floor is not None:
        return floor.n
    if up is not None:
        u = np.asarray(up, float)
        return u / np.linalg.norm(u)
    from rmpl.inference import estimate_up

    return estimate_up(rig)


def monocular_people(
    kp: np.ndarray,
    sc: np.ndarray,
    frame: np.ndarray,
    num_frames: int,
    rig: Rig,
    fps: float | None,
    floor: Floor | None,
    config: MonocularConfig,
    run_config=None,
    lift=None,
    joints: str | None = None,
) -> MonocularResult:
    """Lift the people of one view, then choose their depths with the cues.

    Args:
        kp: the 2D people (M, 1, J_2d, 2) pixels, each in frame ``frame`` (M,); COCO-17 or
            HALPE-26 (the floor cue reads the ankles' rays, joints 15 and 16 of both).
        sc: (M, 1, J_2d).
        num_frames: T.
        rig: one camera.
        fps: frames per second (the time cue needs it; None: 25 is assumed for the
            smoother's window, with the time cue's other steps unchanged).
        floor: the floor, or None.
        config: the cues and their constants.
        run_config: :class:`rmpl.pipeline.runner.RunConfig` (model, tracker settings).
        lift: ``fn(kp, sc, rig) -> (points, num_views)`` instead of the config's lifter.
        joints: the 2D's joint set (None: by its joint count).

    Returns:
        :class:`MonocularResult` of T frames and P people (tracks with "time", else the
        people of each frame in their order, P = the most in one frame), in the lifter's
        joint set.
    """
    from rmpl.geometry.rays import rays_from_keypoints
    from rmpl.pipeline.association import Association
    from rmpl.pipeline.runner import RunConfig, _estimator, estimate

    if len(rig) != 1:
        raise ValueError(f"monocular lifting takes one camera, got {len(rig)}")
    cfg = run_config or RunConfig()
    up = _up(rig, floor, cfg.up)
    cfg = replace(cfg, up=tuple(float(v) for v in up))  # the lifter's up: the floor's normal
    center = rig.centers[0]
    rows = [np.flatnonzero(frame == t) for t in range(num_frames)]
    people = [Association(kp[r], sc[r], np.zeros((len(r), 1), int)) for r in rows]
    fn = lift or _estimator(cfg, joints=joints, floor=floor)
    per_frame, views = estimate(people, rig, cfg, fn=fn)  # lists of (N, J, 3), (N, J)
    J = per_frame[0].shape[-2] if per_frame else COCO17.num_joints
    skeleton = getattr(fn, "skeleton", None) or BY_COUNT.get(J, "coco17")
    pts = np.concatenate(per_frame) if len(kp) else np.zeros((0, J, 3))
    rays = rays_from_keypoints(np.nan_to_num(kp), rig)[:, 0]  # (M, J_2d, 6)
    cues = frame_cues(pts, rays, sc[:, 0], center, floor, up, config)
    log_s, sd = per_frame_log_scale(cues, config)
    scaled = scale_about(pts, center, log_s)  # every joint moves with the depth
    split = np.cumsum([len(r) for r in rows])[:-1]
    if "time" not in config.cues:
        return _by_frame(np.split(scaled, split), np.split(sd, split), views, J, skeleton)
    index, ids = _track_index(np.split(scaled, split), cfg)
    return _with_time(pts, cues, views, rows, index, ids, center, floor, fps, config, skeleton)


def _with_time(pts, cues: FrameCues, views, rows, index, ids, center, floor, fps, config,
               skeleton: str) -> MonocularResult:  # fmt: skip
    """:func:`monocular_people`'s time cue: each track's depth over time
    (:func:`track_log_depth`), in (T, P) slots of the tracker's ``index``."""
    num_frames, P = index.shape
    J = pts.shape[-2]
    out = np.full((num_frames, P, J, 3), np.nan)
    sigma = np.full((num_frames, P), np.nan)
    nv = np.zeros((num_frames, P, J), int)
    times = np.arange(num_frames) / (fps or 25.0)
    offsets = np.r_[0, np.cumsum([len(r) for r in rows])]
    members = np.full((num_frames, P), -1)
    order = np.concatenate(rows) if rows else np.zeros(0, int)  # pts row -> kp row
    depths = []
    for p in range(P):
        t_idx = np.flatnonzero(index[:, p] >= 0)
        m = offsets[t_idx] + index[t_idx, p]  # rows of the track's people
        members[t_idx, p] = order[m]
        sub = FrameCues(cues.floor[m], cues.floor_sd[m], cues.proxy[m], cues.upright[m])
        depth = track_log_depth(pts[m], sub, center, floor, times[t_idx], config)
        root = np.nanmean(pts[m][:, HIPS], axis=1)
        log_r = np.log(np.linalg.norm(root - center, axis=-1))
        out[t_idx, p] = scale_about(pts[m], center, depth.log_depth - log_r)
        sigma[t_idx, p] = depth.sd
        nv[t_idx, p] = np.concatenate(views)[m]
        depths.append(depth)
    return MonocularResult(out, sigma, nv, ids, depths, skeleton, members)


def _track_index(points: list[np.ndarray], cfg):
    """The runner's tracker; a single person everywhere is one track."""
    from rmpl.pipeline.runner import track_index

    if all(len(p) <= 1 for p in points):
        index = np.array([[0 if len(p) else -1] for p in points], int).reshape(len(points), 1)
        return index, np.array([0])
    return track_index(points, cfg)


def _by_frame(points: list, sds: list, views: list, J: int, skeleton: str) -> MonocularResult:
    """Per-frame results in (T, N_max) slots, no identities."""
    T = len(points)
    P = max([len(p) for p in points] + [0])
    out = np.full((T, P, J, 3), np.nan)
    sigma = np.full((T, P), np.nan)
    nv = np.zeros((T, P, J), int)
    for t, (p, s, v) in enumerate(zip(points, sds, views, strict=True)):
        out[t, : len(p)], sigma[t, : len(p)], nv[t, : len(p)] = p, s, v
    return MonocularResult(out, sigma, nv, np.arange(P), [None] * P, skeleton)


def lift_stretch(
    kp, sc, frame, num_frames, rig, fps, floor, config, run_config=None, lift=None, temporal=None
):
    """:func:`monocular_people`, then (with "time") the runner's filters, as predictions; with
    a ``temporal`` lifter (:class:`rmpl.inference_temporal.TemporalLifter`) and "time", each
    track lifted again as a whole by it instead (:func:`temporal_tracks`).

    Returns:
        predictions (M', J, 3) and their frame indices (M',), as a sequence method gives
        them to the evaluation harness.
    """
    from rmpl.pipeline.runner import RunConfig, smooth

    cfg = run_config or RunConfig()
    res = monocular_people(kp, sc, frame, num_frames, rig, fps, floor, config, cfg, lift)
    x = res.points
    if temporal is not None and res.rows is not None and len(x) and fps:
        x, _, _ = temporal_tracks(
            res.rows, kp, sc, rig, fps, floor, temporal, _up(rig, floor, None),
            max_gap=cfg.max_gap,
        )  # fmt: skip
    elif "time" in config.cues and len(x) and fps:
        x, _ = smooth(x, fps, replace(cfg, cutoff=min(cfg.cutoff, 0.45 * fps)))
    t_idx, p_idx = np.nonzero(np.isfinite(x).all(-1).any(-1))
    return x[t_idx, p_idx], t_idx


def lift_single_view(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    frames: np.ndarray | None = None,
    fps: float | None = None,
    floor: Floor | None = None,
    config=None,
    monocular: MonocularConfig | None = None,
    temporal: bool = True,
    joints: str | None = None,
) -> Poses3D:
    """``rmpl run`` / ``rmpl lift`` with one camera: the lifter, then depth from the cues.

    Args:
        keypoints: (T, 1, P, J, 2) pixels (NaN = missing), COCO-17 or HALPE-26 (J = 17 or
            26). scores: (T, 1, P, J).
        rig: one camera.
        frames, fps: as :func:`rmpl.pipeline.runner.run`.
        floor: the floor (:mod:`rmpl.geometry.floor`), or None: the size prior (and time)
            alone.
        config: :class:`rmpl.pipeline.runner.RunConfig` (method "rmpl", a per-frame model,
            or a temporal one that reads the floor: see :func:`temporal_tracks`).
        monocular: the cues (default: :meth:`MonocularConfig.for_model`).
        temporal: apply the runner's filters (:func:`rmpl.pipeline.runner.smooth`); with a
            temporal model, lift whole tracks with it (False: its per-frame model alone).
        joints: the 2D's joint set (None: by its joint count).

    Returns:
        :class:`Poses3D` in the lifter's joint set, per-joint uncertainty = the 50% radius
        of the depth error along the ray (metres), or with a temporal model its own 50%
        error radius.
    """
    from rmpl.inference import checkpoint_reads_floor
    from rmpl.inference_temporal import is_temporal_checkpoint
    from rmpl.pipeline.runner import RunConfig, smooth

    cfg = config or RunConfig()
    if is_temporal_checkpoint(cfg.model):
        return _single_view_temporal(
            keypoints, scores, rig, frames, fps, floor, cfg, temporal, joints
        )
    mono = monocular or MonocularConfig.for_model(cfg.model, floor_known=floor is not None)
    reads_floor = checkpoint_reads_floor(cfg.model)
    guess = _guessed_floor_sd(rig, floor, reads_floor)
    if len(rig) != 1:
        raise ValueError(f"lift_single_view takes one camera, got {len(rig)}")
    T = keypoints.shape[0]
    kp, sc, t_idx = _view_people(keypoints, scores, rig)
    res = monocular_people(kp, sc, t_idx, T, rig, fps, floor, mono, cfg, joints=joints)
    tracks = res.points
    interpolated = np.zeros(tracks.shape[:-1], bool)
    if temporal and len(tracks):
        tracks, interpolated = smooth(tracks, fps, cfg)
    ok = np.isfinite(tracks).all(-1)
    lifted = int(JointSource.LIFTED)
    flags = np.where(interpolated, int(JointSource.INTERPOLATED), np.where(ok, lifted, 0))
    tracks[~ok] = np.nan
    radius = _depth_radius(res.sigma, tracks, ok, rig, temporal, cfg.max_gap, guess)
    _log_summary(res, radius, floor, mono, reads_floor)
    views = np.where(ok, res.views, 0).astype(np.int32)
    return _poses(tracks, flags, views, res, frames, fps, radius)


def _view_people(keypoints: np.ndarray, scores: np.ndarray, rig: Rig):
    """One view's 2D people as rows, keypoints far outside the image dropped.

    Returns:
        kp (M, 1, J_2d, 2), sc (M, 1, J_2d) and each row's frame (M,)."""
    from rmpl.pipeline.runner import drop_far

    keypoints, scores = drop_far(keypoints, scores, rig)
    present = (scores > 0).any(-1)[:, 0]  # (T, P)
    t_idx, p_idx = np.nonzero(present)
    return keypoints[t_idx, :, p_idx], scores[t_idx, :, p_idx], t_idx


def _guessed_floor_sd(rig: Rig, floor: Floor | None, reads_floor: bool) -> float:
    """The log-depth error of a guessed floor (the calibration's convention) for a model that
    reads it, said in a warning; added to the uncertainty only. 0 for any other floor."""
    if not (reads_floor and floor is not None):
        return 0.0
    if not floor.source.startswith("calibration convention"):
        return 0.0
    h = max(float(signed_distance(rig.centers[0], floor)), 0.2)
    log.warning(
        "the floor is the calibration's convention (%s), not measured: a floor off by e "
        "moves the person by about e x distance / %.2f m along the rays (give --floor, or "
        "a multi-view poses file of this rig)", floor.describe(), h,
    )  # fmt: skip
    return CONVENTION_FLOOR_SD / h


def _depth_radius(sigma, tracks, ok, rig: Rig, temporal: bool, max_gap: int, guess: float):
    """The 50% radius of the depth error along each joint's ray (T, P, J), metres, from the
    log-depth sds (T, P); gap-filled frames (``temporal``) take their neighbours' spread."""
    sigma = sigma.copy()
    if temporal and len(tracks):
        from rmpl.pipeline.filters import fill_gaps

        filled, _ = fill_gaps(sigma[..., None, None].repeat(3, -1), max_gap=max_gap)
        sigma = filled[..., 0, 0]
    sigma = np.hypot(sigma, guess)
    radius = RADIUS_50_1D * sigma[..., None] * np.linalg.norm(tracks - rig.centers[0], axis=-1)
    return np.where(ok, radius, np.nan)


def _poses(points, flags, num_views, res: MonocularResult, frames, fps, radius) -> Poses3D:
    T = len(points)
    return Poses3D(
        points=points,
        flags=flags.astype(np.uint8),
        num_views=num_views,
        skeleton=res.skeleton,
        frames=np.arange(T) if frames is None else np.asarray(frames),
        fps=fps,
        person_ids=np.asarray(res.ids),
        uncertainty=radius,
    )


def _single_view_temporal(keypoints, scores, rig, frames, fps, floor, cfg, whole, joints):
    """:func:`lift_single_view` with a temporal model (``cfg.model``): its per-frame model
    finds and follows the people (the time cue), then :func:`temporal_tracks` lifts each
    track as a whole (``whole``; else the per-frame model's answers are kept, their depth
    smoothed along each track; the cues are not used)."""
    from rmpl.inference import Lifter
    from rmpl.inference_temporal import TemporalLifter

    if len(rig) != 1:
        raise ValueError(f"lift_single_view takes one camera, got {len(rig)}")
    if whole and fps is None:
        raise InputError(None, "fps", "the frame rate (--fps) to lift whole tracks", "none")
    temporal = TemporalLifter.from_pretrained(cfg.model)
    if not temporal.reads_floor:
        raise InputError(cfg.model, "model", "a temporal model that reads the floor for one "
                         "camera (or a per-frame model)", "one that does not")  # fmt: skip
    if floor is None:
        log.warning("one camera, a temporal model and no floor: nothing but body size fixes "
                    "the depth (expect errors of 0.5 m or more); give --floor")  # fmt: skip
    frame_lifter = Lifter(temporal.model.frame_model, {})
    up = _up(rig, floor, cfg.up)
    name = BY_COUNT.get(keypoints.shape[-2]) if joints is None else joints

    def lift(kp, sc, rig_):
        r = frame_lifter.lift(kp, sc, rig_, up=up, joints=name, floor=floor)
        return r.points, r.num_views

    lift.skeleton = frame_lifter.skeleton.name
    T = keypoints.shape[0]
    kp, sc, t_idx = _view_people(keypoints, scores, rig)  # (M, 1, J_2d, ...)
    mono = MonocularConfig.from_cues("time", lifter_sd=FLOOR_MODEL_LIFTER_SD)
    res = monocular_people(kp, sc, t_idx, T, rig, fps, floor, mono, cfg, lift, joints)
    detected = (res.rows >= 0)[..., None]  # (T, P, 1) the view sees the track's person
    radius = views = None
    if whole:
        points, radius, views = temporal_tracks(
            res.rows, kp, sc, rig, fps, floor, temporal, up, name, max_gap=cfg.max_gap
        )
    else:
        points = res.points
    ok = np.isfinite(points).all(-1)
    filled = ok & ~detected
    flags = np.where(filled, int(JointSource.INTERPOLATED), np.where(ok, 1, 0))
    points = np.where(ok[..., None], points, np.nan)
    _log_temporal(cfg.model, floor, whole, radius)
    num_views = (ok & detected).astype(np.int32) if views is None else views * ok
    return _poses(points, flags, num_views, res, frames, fps, radius)


def _log_temporal(model: str, floor, whole: bool, radius) -> None:
    """Say where one camera's depth came from with a temporal model, and its error radius."""
    where = floor.describe() if floor is not None else "no floor"
    how = "whole tracks lifted by the temporal model" if whole else "its per-frame model"
    log.info("one camera: %s %s, which reads the floor (%s) and learnt body sizes; depth "
             "comes from them, not from triangulation", how, model, where)  # fmt: skip
    r = radius[np.isfinite(radius)] * 1000 if radius is not None else np.zeros(0)
    if r.size:
        log.info("predicted error radius (50%%): median %.0f mm, 90th percentile %.0f mm "
                 "(per joint in poses.json/npz 'uncertainty')", np.median(r),
                 np.percentile(r, 90))  # fmt: skip


def temporal_tracks(
    rows, kp, sc, rig: Rig, fps, floor, lifter, up=None, joints=None, max_gap: int = 20
):
    """Lift each one-view track as a whole with a temporal lifter.

    A track is cut where the view misses its person for more than ``max_gap`` frames
    (:func:`rmpl.pipeline.tracklift.pieces`, as multi-view tracks are): each piece is lifted
    on its own, and the frames between pieces stay empty.

    Args:
        rows: (T, P) the row of ``kp`` each track is in each frame, -1 none
            (:attr:`MonocularResult.rows`).
        kp, sc: the 2D people (M, 1, J_2d, 2), (M, 1, J_2d).
        rig: one camera. fps: frames per second. floor: the floor or None.
        lifter: a :class:`rmpl.inference_temporal.TemporalLifter`. up: the world's up.
        joints: the 2D's joint set.
        max_gap: the longest miss (frames) a piece bridges (``RunConfig.max_gap``).

    Returns:
        points (T, P, J, 3) metres, their 50% error radius (T, P, J) metres and the number
        of views that saw each joint (T, P, J), 0 or 1; NaN (0) outside a track's pieces.
        Frames inside a piece where the view misses the person are the network's fill.
    """
    from rmpl.pipeline.tracklift import pieces

    T, P = rows.shape
    J = lifter.num_joints
    points, radius = np.full((T, P, J, 3), np.nan), np.full((T, P, J), np.nan)
    views = np.zeros((T, P, J), np.int32)
    for p in range(P):
        have = rows[:, p] >= 0
        for a, b in pieces(have, max_gap):
            h = have[a:b]
            tk = np.full((b - a, *kp.shape[1:]), np.nan)
            ts = np.zeros((b - a, *sc.shape[1:]))
            tk[h], ts[h] = kp[rows[a:b][h, p]], sc[rows[a:b][h, p]]
            track = lifter.lift_track(tk, ts, rig, fps=fps, up=up, joints=joints, floor=floor)
            points[a:b, p], radius[a:b, p] = track.points, track.radius(0.5)
            views[a:b, p] = track.num_views
    return points, radius, views


def _log_summary(
    res: MonocularResult, radius: np.ndarray, floor, mono: MonocularConfig, reads_floor=False
) -> None:
    """Say plainly where depth came from and how uncertain it is."""
    cues = ", ".join(mono.cues) or "none"
    where = floor.describe() if floor is not None else "no floor (size prior and time only)"
    if reads_floor:
        cues = f"the lifter's own, learnt from the floor and body sizes; then {cues}"
        if floor is None:
            where = "no floor (body size and time only: expect a coarse depth)"
    log.info(
        "one camera: depth along the rays comes from priors, not from triangulation (cues: "
        "%s); floor: %s", cues, where,
    )  # fmt: skip
    for p, depth in enumerate(res.tracks):
        if depth is None:
            continue
        n = int(np.isfinite(depth.log_depth).sum())
        if "floor" not in mono.cues and "size" not in mono.cues:
            log.info("person %d: %d frames, the lifter's depth smoothed along the track",
                     int(res.ids[p]), n)  # fmt: skip
            continue
        log.info(
            "person %d: %d frames, %d with the feet on the floor (%.0f%%); stature %.2f m "
            "+- %.2f%s", int(res.ids[p]), n, int(depth.contact.sum()),
            100 * depth.contact.sum() / max(n, 1), depth.stature, depth.stature_sd,
            "; floor dropped: the floor-implied stature is implausible" if depth.floor_dropped
            else "",
        )  # fmt: skip
    r = radius[np.isfinite(radius)] * 1000
    if r.size:
        log.info(
            "depth uncertainty (50%% radius along each joint's ray, from the cue noise model; "
            "the lifter's shape error comes on top): median %.0f mm, 90th percentile %.0f mm "
            "(per joint in poses.json/npz 'uncertainty')", np.median(r), np.percentile(r, 90),
        )  # fmt: skip
