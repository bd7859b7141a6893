"""Synchronise cameras from the motion of the people they film.

Consumer cameras start recording at different instants. :func:`find_sync` finds each
camera's time offset from the 2D keypoints alone (coarse) and, given a calibration, to a
fraction of a frame (fine):

- **coarse:** each view's people are linked frame to frame (:func:`link_people`); the
  view's motion is the summed speed of its people's joints, each in body sizes per second
  (any number of people, independent of the camera's distance). Every pair of views is
  cross-correlated (normalised, over the overlap) at every lag up to ``max_offset``
  seconds on a common time grid (the highest frame rate), and the offsets are the weighted
  least-squares solution of the pairs' peaks, rounded to whole frames of each camera.
- **with a calibration** (:mod:`rmpl.calibration.sync_3d`): the offsets, whole frames and
  then a fraction, at which the views' people agree best through the cameras (the
  epipolar distance of each joint from its match in every other view), every camera
  solved jointly against every other over every whole-frame lag up to ``max_offset``
  seconds; the coarse stage is not needed there.

Convention: ``offset_seconds`` of a camera is how far its clock is ahead of the
reference's: the instant the reference records at time ``s`` (its frame ``s * fps_ref``)
is this camera's frame ``(s + offset_seconds) * fps``. A camera that started recording 2 s
before the reference has ``offset_seconds = 2``. The reference (the first view) has 0.

A recording whose motion does not decide (a static scene, a peak or valley no clearer
than the others) is refused with an :class:`~rmpl.errors.InputError`, never guessed.

Shape glossary: ``T`` frames, ``V`` views, ``P`` people, ``J`` joints.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from rmpl.calibration.sync_base import (  # noqa: F401  (people.py and sync_3d use them)
    _essential,
    _normalised,
    _quiet,
    _sizes,
    link_index,
    link_people,
)
from rmpl.errors import InputError

__all__ = [
    "MIN_PEAK",
    "MIN_MARGIN",
    "Sync",
    "apply_sync",
    "coarse_offsets",
    "find_sync",
    "link_index",
    "link_people",
    "motion_speed",
    "read_sync",
    "write_sync",
]

log = logging.getLogger(__name__)

#: A pair of views decides an offset only when its correlation peak reaches this value...
MIN_PEAK = 0.3
#: ... and stands this much above the highest correlation outside its neighbourhood.
MIN_MARGIN = 0.1
#: The peak's neighbourhood, seconds (a broad peak of slow motion is one peak).
PEAK_WIDTH = 0.2
#: Fewest overlapping samples (of the common grid) a lag needs, and the least share of the
#: shorter view's samples (a short overlap correlates by chance).
MIN_OVERLAP = 20
MIN_OVERLAP_FRACTION = 0.5
#: ... and the peak must beat the best other correlation by this many standard errors.
MIN_Z = 3.0
_FORMAT = "rmpl.sync"


@dataclass(frozen=True)
class Sync:
    """Each camera's time offset.

    Attributes:
        views: camera names, length V; ``views[0]`` is the reference.
        fps: frames per second of each camera, shape (V,).
        offsets: seconds, shape (V,): how far each camera's clock is ahead of the
            reference's (see the module docstring).
        confidence: shape (V,), in [0, 1]: the correlation peak of the camera's pairs
            that agree with the solution (1 for the reference).
        method: ``"motion"`` (whole frames, from the 2D motion alone), ``"3d"`` (whole
            frames, from the views' agreement through a calibration) or ``"3d-fine"``
            (to a fraction of a frame).
        residual: per camera, the mean epipolar disagreement at the offset, pixels
            (NaN without a calibration).
        uncertainty: per camera, the offset's standard error in its own frames (NaN
            unless found to a fraction of a frame; 0 for the reference).
    """

    views: list[str]
    fps: np.ndarray
    offsets: np.ndarray
    confidence: np.ndarray
    method: str = "motion"
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    uncertainty: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def offset_frames(self) -> np.ndarray:
        """Offsets in each camera's own frames, shape (V,)."""
        return self.offsets * self.fps

    def to_dict(self) -> dict:
        res = self.residual if len(self.residual) else np.full(len(self.views), np.nan)
        err = self.uncertainty if len(self.uncertainty) else np.full(len(self.views), np.nan)
        cams = {}
        for v, name in enumerate(self.views):
            frames = float(self.offset_frames[v])
            cams[name] = {
                "offset_frames": round(frames, 3)
                if self.method.endswith("fine")
                else int(round(frames)),
                "offset_seconds": round(float(self.offsets[v]), 6),
                "fps": float(self.fps[v]),
                "confidence": round(float(self.confidence[v]), 3),
                "epipolar_px": None if not np.isfinite(res[v]) else round(float(res[v]), 3),
                "uncertainty_frames": None if np.isnan(err[v]) else round(float(err[v]), 3),
            }
        return {
            "format": _FORMAT,
            "version": 1,
            "reference": self.views[0],
            "method": self.method,
            "convention": "offset_seconds: how far the camera's clock is ahead of the "
            "reference's; the reference's time s is the camera's frame (s + offset_seconds) * fps",
            "cameras": cams,
        }


# --------------------------------------------------------------------------- people in time


def motion_speed(tracks: np.ndarray, fps: float, max_step: float = 0.5) -> np.ndarray:
    """A view's motion: the summed joint speed of its people, body sizes per second.

    Args:
        tracks: one view's linked people, shape (T, Q, J, 2) (:func:`link_people`).
        fps: the view's frame rate.
        max_step: a joint moving more than this many body sizes in one frame is a
            detector error and counts as this much.

    Returns:
        Shape (T,): NaN in the first frame and where nobody is seen in two successive
        frames.
    """
    size = np.nanmedian(np.where(np.isfinite(_sizes(tracks)), _sizes(tracks), np.nan), axis=0)
    step = np.linalg.norm(np.diff(tracks, axis=0), axis=-1) / np.maximum(size, 1.0)[None, :, None]
    step = np.minimum(step, max_step)  # (T-1, Q, J)
    with _quiet():
        per_person = np.nanmean(step, axis=-1)  # (T-1, Q)
    seen = np.isfinite(per_person).any(-1)
    speed = np.where(seen, np.nansum(per_person, -1), np.nan) * fps
    return np.concatenate([[np.nan], speed])


# --------------------------------------------------------------------------- coarse


def _ncc_curve(a: np.ndarray, b: np.ndarray, lags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalised correlation of a(t) with b(t + lag) over their overlap, per lag, and its
    standard error: 1 / sqrt of the overlap's effective samples (two AR(1) signals:
    n (1 - ra rb) / (1 + ra rb), ra and rb their lag-one autocorrelations). Lags whose
    overlap is under :data:`MIN_OVERLAP_FRACTION` of the shorter signal are NaN."""
    out, se = np.full(len(lags), np.nan), np.full(len(lags), np.nan)
    n = len(a)
    shorter = min(np.isfinite(a).sum(), np.isfinite(b).sum())
    need = max(MIN_OVERLAP, int(np.ceil(MIN_OVERLAP_FRACTION * shorter)))
    for i, L in enumerate(lags):
        lo, hi = max(0, -L), min(n, len(b) - L)
        if hi - lo < need:
            continue
        x, y = a[lo:hi], b[lo + L : hi + L]
        ok = np.isfinite(x) & np.isfinite(y)
        if ok.sum() < need:
            continue
        x, y = x[ok] - x[ok].mean(), y[ok] - y[ok].mean()
        den = np.sqrt((x * x).sum() * (y * y).sum())
        if den > 0:
            out[i] = (x * y).sum() / den
            rr = _lag_one(x) * _lag_one(y)
            se[i] = 1.0 / np.sqrt(max(ok.sum() * (1 - rr) / (1 + rr), 1.0))
    return out, se


def _lag_one(x: np.ndarray) -> float:
    den = float((x * x).sum())
    return min(max(float((x[1:] * x[:-1]).sum()) / den, 0.0), 0.99) if den > 0 else 0.0


def _peak(curve: np.ndarray, se: np.ndarray, lags: np.ndarray, width: int):
    """(lag, peak, margin above the best other local maximum more than ``width`` samples
    away, and that margin in standard errors)."""
    if not np.isfinite(curve).any():
        return 0, float("nan"), 0.0, 0.0
    i = int(np.nanargmax(curve))
    far = np.abs(lags - lags[i]) > width
    c = np.where(np.isfinite(curve), curve, -np.inf)
    left, right = np.r_[-np.inf, c[:-1]], np.r_[c[1:], -np.inf]
    other_peak = (c >= left) & (c >= right)  # local maxima (the ends included): not the
    rest = np.flatnonzero(far & other_peak & np.isfinite(curve))  # peak's own shoulders
    if not len(rest):
        return int(lags[i]), float(curve[i]), float(curve[i]), 0.0
    k = rest[np.argmax(curve[rest])]
    margin = float(curve[i] - max(curve[k], 0.0))
    z = float((curve[i] - curve[k]) / np.hypot(se[i], se[k]))
    return int(lags[i]), float(curve[i]), margin, z


def _on_grid(speed: np.ndarray, fps: float, rate: float, length: float) -> np.ndarray:
    t = np.arange(int(np.floor(length * rate)) + 1) / rate
    src = np.arange(len(speed)) / fps
    out = np.interp(t, src, np.nan_to_num(speed), left=np.nan, right=np.nan)
    near = np.clip(np.round(t * fps).astype(int), 0, len(speed) - 1)
    return np.where(np.isfinite(speed[near]), out, np.nan)


def coarse_offsets(
    speeds: list[np.ndarray], fps: np.ndarray, views: list[str], max_offset: float, source=None
) -> tuple[np.ndarray, np.ndarray]:
    """Offsets (seconds, shape (V,)) and confidences from the views' motion speeds.

    Raises:
        InputError: a camera whose offset the motion does not decide.
    """
    V = len(speeds)
    rate = float(np.max(fps))
    length = max(len(s) / f for s, f in zip(speeds, fps, strict=True))
    grid = [_on_grid(s, f, rate, length) for s, f in zip(speeds, fps, strict=True)]
    max_lag = int(np.ceil(max_offset * rate))
    lags = np.arange(-max_lag, max_lag + 1)
    width = max(2, int(round(PEAK_WIDTH * rate)))
    pairs = []  # (i, j, lag, peak): b's clock ahead of a's by lag
    for i in range(V):
        for j in range(i + 1, V):
            lag, peak, margin, z = _peak(*_ncc_curve(grid[i], grid[j], lags), lags, width)
            log.debug("sync %s-%s: lag %d, peak %.3f, margin %.3f, z %.1f", views[i], views[j],
                      lag, peak, margin, z)  # fmt: skip
            if peak >= MIN_PEAK and margin >= MIN_MARGIN and z >= MIN_Z:
                pairs.append((i, j, lag, peak))
    offsets = _solve_pairs(pairs, V, views, source)
    conf = np.ones(V)
    for v in range(1, V):
        agree = [p for i, j, lag, p in pairs if v in (i, j)
                 and abs(offsets[j] - offsets[i] - lag) <= 1.0]  # fmt: skip
        conf[v] = max(agree) if agree else 0.0
    return offsets / rate, conf


def _solve_pairs(pairs, V: int, views: list[str], source) -> np.ndarray:
    """Least-squares offsets (grid samples) from pairwise lags, weighted by their peaks,
    with pairs that disagree with the rest by more than one sample dropped."""
    decided = _connected(pairs, V)
    if not decided.all():
        missing = [views[v] for v in np.flatnonzero(~decided)]
        raise InputError(
            source,
            "motion",
            "enough motion of the people seen by every camera to decide its offset "
            f"(a correlation peak >= {MIN_PEAK:.2f} standing {MIN_MARGIN:.2f} and {MIN_Z:g} "
            "standard errors above the rest, over at least half the recording; a calibration "
            "(--calib) decides from the views' agreement instead)",
            f"no decision for camera(s) {missing}",
        )
    for _ in range(V * V):
        A = np.zeros((len(pairs) + 1, V))
        b = np.zeros(len(pairs) + 1)
        w = np.ones(len(pairs) + 1)
        for k, (i, j, lag, peak) in enumerate(pairs):
            A[k, i], A[k, j], b[k], w[k] = -1.0, 1.0, lag, peak
        A[-1, 0] = 1.0  # the reference at 0
        x = np.linalg.lstsq(A * w[:, None], b * w, rcond=None)[0]
        res = np.abs(A[:-1] @ x - b[:-1])
        if not len(res) or res.max() <= 1.0:
            return np.round(x - x[0])
        worst = int(np.argmax(res))
        rest = pairs[:worst] + pairs[worst + 1 :]
        if not _connected(rest, V).all():
            return np.round(x - x[0])
        pairs = rest
    return np.round(x - x[0])


def _connected(pairs, V: int) -> np.ndarray:
    seen = np.zeros(V, bool)
    seen[0] = True
    for _ in range(V):
        for i, j, *_ in pairs:
            if seen[i] or seen[j]:
                seen[i] = seen[j] = True
    return seen


# --------------------------------------------------------------------------- fine


def _sample(tracks: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Tracks (T, Q, J, 2) at fractional frames (S,): linear between the two frames
    around each; NaN outside the recording or where either frame misses the joint."""
    T = len(tracks)
    f0 = np.floor(frames).astype(int)
    a = (frames - f0)[:, None, None, None]
    ok = (f0 >= 0) & (f0 < T)
    i0 = np.clip(f0, 0, T - 1)
    i1 = np.clip(f0 + 1, 0, T - 1)
    x0, x1 = tracks[i0], tracks[i1]
    exact = np.isclose(a, 0.0)
    out = np.where(exact, x0, (1 - a) * x0 + a * x1)
    out[~ok] = np.nan
    return out


def find_sync(
    keypoints: np.ndarray,
    fps: float | np.ndarray,
    views: list[str],
    rig=None,
    max_offset: float = 3.0,
    source=None,
    fine: bool = True,
) -> Sync:
    """Each camera's offset from the 2D motion (coarse) and, with ``rig``, its fraction.

    Args:
        keypoints: shape (T, V, P, J, 2), pixels, NaN = missing; each view's own frames
            (frame ``t`` of two views need not be one instant). People need not keep
            their index across frames or views.
        fps: frame rate, one value or one per view (V,).
        views: camera names, length V; the first is the reference.
        rig: the V cameras (intrinsics and extrinsics) for the fine stage, or None.
        max_offset: largest offset searched, seconds.
        source: the input's name, for messages.

    Raises:
        InputError: fewer than two views, no frame rate, a view without people, or motion
            that does not decide an offset.
    """
    kp = np.asarray(keypoints, float)
    V = kp.shape[1]
    fps = np.broadcast_to(np.asarray(fps, float), (V,)).copy()
    _check(kp, fps, views, rig, source)
    if rig is None:
        tracks = [link_people(kp[:, v]) for v in range(V)]
        speeds = [_trim(motion_speed(tr, f)) for tr, f in zip(tracks, fps, strict=True)]
        offsets, conf = coarse_offsets(speeds, fps, views, max_offset, source)
        offsets = np.round(offsets * fps) / fps  # whole frames of each camera
        return Sync(list(views), fps, offsets, conf, "motion")
    from rmpl.calibration.sync_3d import agreement_offsets

    off, conf, resid, err = agreement_offsets(kp, fps, rig, max_offset, list(views), source,
                                              fine)  # fmt: skip
    return Sync(list(views), fps, off - off[0], conf, "3d-fine" if fine else "3d", resid, err)


def _trim(speed: np.ndarray) -> np.ndarray:
    """The speed up to the view's last frame with people (padding frames are not motion)."""
    seen = np.flatnonzero(np.isfinite(speed))
    return speed[: seen[-1] + 1] if len(seen) else speed


def _check(kp: np.ndarray, fps: np.ndarray, views, rig, source) -> None:
    V = kp.shape[1]
    if V < 2:
        raise InputError(source, "views", "two or more cameras to synchronise", V)
    if len(views) != V:
        raise InputError(source, "views", f"{V} view names", views)
    if not (np.isfinite(fps).all() and (fps > 0).all()):
        raise InputError(source, "fps", "a positive frame rate (--fps) for every camera", fps)
    for v in range(V):
        seen = (np.isfinite(kp[:, v]).all(-1).sum(-1) >= 3).any(-1)
        if seen.sum() < MIN_OVERLAP:
            raise InputError(source, f"view {views[v]}", f"a person in at least "
                             f"{MIN_OVERLAP} frames", f"{int(seen.sum())} frames")  # fmt: skip
    if rig is not None and len(rig) != V:
        raise InputError(source, "cameras", f"{V} cameras, one per view", len(rig))


# --------------------------------------------------------------------------- files


def write_sync(sync: Sync, path: str | Path) -> Path:
    """Write ``sync.json`` atomically; returns the path."""
    from rmpl.io.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(sync.to_dict(), indent=1) + "\n", encoding="utf-8")
    return path


def read_sync(path: str | Path) -> Sync:
    """Read a ``sync.json`` written by :func:`write_sync`.

    Raises:
        InputError: not a sync file, or a field missing or of the wrong kind.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise InputError(path, None, "a readable sync.json", type(e).__name__) from None
    if not isinstance(doc, dict) or doc.get("format") != _FORMAT:
        raise InputError(path, "format", f"{_FORMAT!r}", None if not isinstance(doc, dict)
                         else doc.get("format"))  # fmt: skip
    cams = doc.get("cameras")
    if not isinstance(cams, dict) or not cams:
        raise InputError(path, "cameras", "a table of cameras", cams)
    views = list(cams)
    vals = {}
    for key in ("offset_seconds", "fps", "confidence"):
        try:
            vals[key] = np.array([float(cams[v][key]) for v in views])
        except (KeyError, TypeError, ValueError):
            raise InputError(path, f"cameras.*.{key}", "a number for every camera") from None
    if not np.isfinite(vals["offset_seconds"]).all() or not (vals["fps"] > 0).all():
        raise InputError(path, "cameras", "finite offsets and positive frame rates")
    method = str(doc.get("method", "motion"))
    return Sync(views, vals["fps"], vals["offset_seconds"], vals["confidence"], method)


def apply_sync(keypoints2d, sync: Sync, source=None):
    """The 2D on the reference's clock: whole frames by shifting, fractions by
    interpolating each view's linked people between its two nearest frames.

    Args:
        keypoints2d: a :class:`~rmpl.io.keypoints.Keypoints2D` whose views are named like
            the cameras of ``sync`` (any order).
        sync: the offsets.

    Returns:
        A Keypoints2D on the reference's frames (the reference's frame numbers and frame
        rate); a view's frame is NaN where that view did not record the instant.

    Raises:
        InputError: a view that ``sync`` does not name.
    """
    from rmpl.io.keypoints import Keypoints2D

    kp = keypoints2d
    missing = [v for v in kp.views if v not in sync.views]
    if missing and not set(kp.views) & set(sync.views) and len(kp.views) == len(sync.views):
        # one named like the 2D files, the other like the calibration: by order, as the
        # run pairs the views with the cameras
        log.info("sync file's cameras %s taken for the views %s, by order", sync.views, kp.views)
        sync = replace(sync, views=list(kp.views))
        missing = []
    if missing:
        raise InputError(source, "views", f"views named like the cameras of the sync file "
                         f"{sync.views}", missing)  # fmt: skip
    by_name = {n: i for i, n in enumerate(sync.views)}
    ref = sync.views[0] if sync.views[0] in kp.views else kp.views[0]
    ref_fps = float(sync.fps[by_name[ref]])
    T = kp.num_frames
    times = np.arange(T) / ref_fps - sync.offsets[by_name[ref]]  # on the sync's clock
    per_view, per_score = [], []
    for v, name in enumerate(kp.views):
        i = by_name[name]
        frames = (times + sync.offsets[i]) * sync.fps[i]
        xy, sc = _shift_view(kp.keypoints[:, v], kp.scores[:, v], frames)
        per_view.append(xy)
        per_score.append(sc)
    Q = max(x.shape[1] for x in per_view)
    xy = np.full((T, kp.num_views, Q, kp.num_joints, 2), np.nan)
    sc = np.zeros((T, kp.num_views, Q, kp.num_joints))
    for v in range(kp.num_views):
        xy[:, v, : per_view[v].shape[1]] = per_view[v]
        sc[:, v, : per_score[v].shape[1]] = per_score[v]
    sc[~np.isfinite(xy).all(-1)] = 0.0
    return Keypoints2D(xy, sc, kp.skeleton, list(kp.views), kp.frames, ref_fps)


def _shift_view(xy: np.ndarray, sc: np.ndarray, frames: np.ndarray):
    """One view at fractional frames: (T, P, J, 2) + (T, P, J) -> the same at ``frames``."""
    whole = np.isclose(frames, np.round(frames), atol=1e-6)
    if whole.all():
        idx = np.round(frames).astype(int)
        ok = (idx >= 0) & (idx < len(xy))
        out, outs = np.full_like(xy, np.nan), np.zeros_like(sc)
        out[ok], outs[ok] = xy[idx[ok]], sc[idx[ok]]
        return out, outs
    tracks, scores = link_people(xy, sc)
    out = _sample(np.concatenate([tracks, scores[..., None]], -1), frames)
    return out[..., :2], np.nan_to_num(out[..., 2])


def synced_inputs(inputs, sync: str | None, source=None):
    """``rmpl run --sync``: the run's inputs on the reference camera's clock.

    Args:
        inputs: :class:`rmpl.pipeline.inputs.Inputs` (views in the rig's order).
        sync: None (as recorded), a ``sync.json`` path, or ``"auto"`` (found now from
            the people in view through the run's calibration, :func:`find_sync`).

    Returns:
        The inputs with the 2D shifted / interpolated (:func:`apply_sync`) and ``sync``
        set to the offsets used (``sync.json``'s document, for the run report).
    """

    from rmpl.io.keypoints import Keypoints2D

    if sync is None:
        return inputs
    kp = Keypoints2D(inputs.keypoints, inputs.scores, inputs.skeleton, inputs.rig.names,
                     inputs.frames, inputs.fps)  # fmt: skip
    if sync == "auto":
        if not inputs.fps:
            raise InputError(source, "--fps", "the frame rate, to synchronise (--sync auto)")
        found = find_sync(kp.keypoints, inputs.fps, kp.views, inputs.rig, source=source)
    else:
        found = read_sync(sync)
    out = apply_sync(kp, found, source)
    doc = found.to_dict()
    doc["source"] = "auto" if sync == "auto" else str(sync)
    log.info("synchronised (%s): offsets %s frames", doc["source"],
             {n: c["offset_frames"] for n, c in doc["cameras"].items()})  # fmt: skip
    return replace(inputs, keypoints=out.keypoints, scores=out.scores,
                   frames=np.asarray(out.frames), fps=out.fps, sync=doc)  # fmt: skip
