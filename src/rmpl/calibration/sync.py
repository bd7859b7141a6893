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
- **fine:** with a calibration, each camera's offset is searched within one frame of the
  coarse one for the value at which its people agree best with every other view: the
  median distance of each joint from the epipolar line of its match (pixels), what the
  reprojection residual of a two-view triangulation measures; the 2D is interpolated
  between frames. The minimum is refined by a parabola.

Convention: ``offset_seconds`` of a camera is how far its clock is ahead of the
reference's: the instant the reference records at time ``s`` (its frame ``s * fps_ref``)
is this camera's frame ``(s + offset_seconds) * fps``. A camera that started recording 2 s
before the reference has ``offset_seconds = 2``. The reference (the first view) has 0.

A recording whose motion does not decide (a static scene, a peak no higher than the
others) is refused with an :class:`~rmpl.errors.InputError`, never guessed.

Shape glossary: ``T`` frames, ``V`` views, ``P`` people, ``J`` joints.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rmpl.errors import InputError

__all__ = [
    "MIN_PEAK",
    "MIN_MARGIN",
    "Sync",
    "apply_sync",
    "coarse_offsets",
    "fine_offsets",
    "find_sync",
    "link_index",
    "link_people",
    "motion_speed",
    "read_sync",
    "scan_offsets",
    "write_sync",
]

log = logging.getLogger(__name__)

#: A pair of views decides an offset only when its correlation peak reaches this value...
MIN_PEAK = 0.3
#: ... and stands this much above the highest correlation outside its neighbourhood.
MIN_MARGIN = 0.1
#: The peak's neighbourhood, seconds (a broad peak of slow motion is one peak).
PEAK_WIDTH = 0.2
#: Fewest overlapping samples (of the common grid) a lag needs.
MIN_OVERLAP = 20
#: Fine search: half-width in frames of the camera, and step.
FINE_HALF_WIDTH = 1.0
FINE_STEP = 0.1
#: A joint's epipolar distance is capped at this many pixels (a wrong match or joint).
EPIPOLAR_CAP = 30.0
#: Whole-frame scan: the best lag's valley must be this deep under the curve's median
#: (pixels), and the next valley higher by this fraction of that depth.
MIN_DEPTH = 0.5
MIN_PROMINENCE = 0.2
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
        residual: per camera, the fine stage's median epipolar distance at the
            offset, pixels (NaN without it).
    """

    views: list[str]
    fps: np.ndarray
    offsets: np.ndarray
    confidence: np.ndarray
    method: str = "motion"
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def offset_frames(self) -> np.ndarray:
        """Offsets in each camera's own frames, shape (V,)."""
        return self.offsets * self.fps

    def to_dict(self) -> dict:
        res = self.residual if len(self.residual) else np.full(len(self.views), np.nan)
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


def _ncc_curve(a: np.ndarray, b: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """Normalised correlation of a(t) with b(t + lag) over their overlap, per lag."""
    out = np.full(len(lags), np.nan)
    n = len(a)
    for i, L in enumerate(lags):
        lo, hi = max(0, -L), min(n, len(b) - L)
        if hi - lo < MIN_OVERLAP:
            continue
        x, y = a[lo:hi], b[lo + L : hi + L]
        ok = np.isfinite(x) & np.isfinite(y)
        if ok.sum() < MIN_OVERLAP:
            continue
        x, y = x[ok] - x[ok].mean(), y[ok] - y[ok].mean()
        den = np.sqrt((x * x).sum() * (y * y).sum())
        out[i] = (x * y).sum() / den if den > 0 else np.nan
    return out


def _peak(curve: np.ndarray, lags: np.ndarray, width: int) -> tuple[int, float, float]:
    """(lag, peak, margin above the best correlation outside ``width`` samples)."""
    if not np.isfinite(curve).any():
        return 0, float("nan"), 0.0
    i = int(np.nanargmax(curve))
    far = np.abs(lags - lags[i]) > width
    rest = curve[far & np.isfinite(curve)]
    second = float(rest.max()) if len(rest) else -1.0
    return int(lags[i]), float(curve[i]), float(curve[i] - max(second, 0.0))


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
            lag, peak, margin = _peak(_ncc_curve(grid[i], grid[j], lags), lags, width)
            log.debug("sync %s-%s: lag %d, peak %.3f, margin %.3f", views[i], views[j], lag,
                      peak, margin)  # fmt: skip
            if peak >= MIN_PEAK and margin >= MIN_MARGIN:
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
            f"(a correlation peak >= {MIN_PEAK:.2f} standing {MIN_MARGIN:.2f} above the rest)",
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


def _normalised(points: np.ndarray, cam) -> np.ndarray:
    from rmpl.geometry.camera import undistort

    K = cam.K
    v = (points[..., 1] - K[1, 2]) / K[1, 1]
    u = (points[..., 0] - K[0, 2] - K[0, 1] * v) / K[0, 0]
    return undistort(np.stack([u, v], -1), cam.dist)


def _epipolar_cost(xa: np.ndarray, xb: np.ndarray, E: np.ndarray, focal: float) -> float:
    """Median over frames and people of a of the best-matching person of b's median
    joint distance from the epipolar lines (pixels). xa (S, Qa, J, 2), xb (S, Qb, J, 2),
    normalised coordinates; E maps a to lines in b."""
    ha = np.concatenate([xa, np.ones(xa.shape[:-1] + (1,))], -1)
    hb = np.concatenate([xb, np.ones(xb.shape[:-1] + (1,))], -1)
    la = np.einsum("ij,...j->...i", E, ha)  # lines in b, (S, Qa, J, 3)
    lb = np.einsum("ji,...j->...i", E, hb)  # lines in a, (S, Qb, J, 3)
    num = np.abs(np.einsum("sajk,sbjk->sabj", la, hb))  # (S, Qa, Qb, J)
    da = num / np.linalg.norm(la[..., :2], axis=-1)[:, :, None]
    db = num / np.linalg.norm(lb[..., :2], axis=-1)[:, None]
    d = np.minimum(0.5 * (da + db) * focal, EPIPOLAR_CAP)
    with _quiet():
        per_pair = np.nanmedian(d, axis=-1)  # (S, Qa, Qb)
        best = np.nanmin(per_pair, axis=-1)  # (S, Qa)
    best = best[np.isfinite(best)]
    return float(np.mean(best)) if len(best) >= MIN_OVERLAP else np.nan


def _essential(rig, a: int, b: int) -> np.ndarray:
    """E with x_b^T E x_a = 0 for normalised points of cameras a and b."""
    Ra, ta, Rb, tb = rig[a].R, rig[a].t, rig[b].R, rig[b].t
    R = Rb @ Ra.T
    t = tb - R @ ta
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return tx @ R


def fine_offsets(
    tracks: list[np.ndarray], fps: np.ndarray, offsets: np.ndarray, rig, sweeps: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Sub-frame offsets (seconds, (V,)) minimising the views' epipolar disagreement,
    each searched within :data:`FINE_HALF_WIDTH` frames of ``offsets``; and the
    disagreement at the answer (pixels, (V,))."""
    V = len(tracks)
    norm = [_normalised(tr, rig[v]) for v, tr in enumerate(tracks)]
    focal = [float(np.mean(np.diag(rig[v].K)[:2])) for v in range(V)]
    E = {(a, b): _essential(rig, a, b) for a in range(V) for b in range(V) if a != b}
    rate = float(fps[0])
    times = np.arange(len(tracks[0])) / rate  # the reference's samples
    off = np.asarray(offsets, float).copy()
    resid = np.full(V, np.nan)

    def cost(v: int, o: float, others: np.ndarray) -> float:
        xv = _sample(norm[v], (times + o) * fps[v])
        total = []
        for w in range(V):
            if w != v:
                xw = _sample(norm[w], (times + others[w]) * fps[w])
                total.append(_epipolar_cost(xv, xw, E[(v, w)], focal[w]))
        return float(np.nanmean(total)) if np.isfinite(total).any() else np.nan

    steps = np.arange(-FINE_HALF_WIDTH, FINE_HALF_WIDTH + 1e-9, FINE_STEP)
    for _ in range(sweeps):
        for v in range(1, V):
            cand = off[v] + steps / fps[v]
            c = np.array([cost(v, o, off) for o in cand])
            if not np.isfinite(c).any():
                continue
            k = int(np.nanargmin(c))
            off[v] = _parabola(cand, c, k)
            resid[v] = c[k]
    resid[0] = np.nanmean([cost(0, 0.0, off)])
    return off, resid


def _parabola(x: np.ndarray, y: np.ndarray, k: int) -> float:
    if 0 < k < len(x) - 1 and np.isfinite(y[k - 1 : k + 2]).all():
        den = y[k - 1] - 2 * y[k] + y[k + 1]
        if den > 0:
            return float(x[k] + 0.5 * (y[k - 1] - y[k + 1]) / den * (x[1] - x[0]))
    return float(x[k])


def scan_offsets(
    tracks: list[np.ndarray], fps: np.ndarray, rig, max_offset: float, views, source=None
) -> tuple[np.ndarray, np.ndarray]:
    """Whole-frame offsets (seconds, (V,)) at which every view's people agree best with
    the other views' (epipolar distance, :func:`fine_offsets`'s measure), searched over
    every lag up to ``max_offset`` seconds; and each camera's confidence, 1 - its best
    disagreement over the best one at least :data:`PEAK_WIDTH` seconds away.

    Cameras are placed one by one, each against those placed before (the one that agrees
    most clearly first), then each again against all the others.

    Raises:
        InputError: a camera whose best lag is not clearly better than the others.
    """
    V = len(tracks)
    norm = [_normalised(tr, rig[v]) for v, tr in enumerate(tracks)]
    focal = [float(np.mean(np.diag(rig[v].K)[:2])) for v in range(V)]
    times = np.arange(len(tracks[0])) / fps[0]
    off, conf = np.zeros(V), np.ones(V)

    def place(v: int, others: list[int]) -> tuple[float, float]:
        lags = np.arange(-np.ceil(max_offset * fps[v]), np.ceil(max_offset * fps[v]) + 1)
        ref = [_sample(norm[w], (times + off[w]) * fps[w]) for w in others]
        c = np.full(len(lags), np.nan)
        for k, L in enumerate(lags):
            xv = _sample(norm[v], times * fps[v] + L)
            d = [_epipolar_cost(xv, xw, _essential(rig, v, w), focal[w])
                 for w, xw in zip(others, ref, strict=True)]  # fmt: skip
            c[k] = np.nanmean(d) if np.isfinite(d).any() else np.nan
        return _decide(c, lags, fps[v], views[v], source)

    placed, pending = [0], list(range(1, V))
    while pending:  # the camera that agrees most clearly with those placed goes next
        tries = {}
        for v in pending:
            try:
                tries[v] = place(v, placed)
            except InputError as e:
                tries[v] = e
        good = {v: r for v, r in tries.items() if not isinstance(r, InputError)}
        if not good:
            raise next(iter(tries.values()))
        v = max(good, key=lambda u: good[u][1])
        off[v], conf[v] = good[v]
        placed.append(v)
        pending.remove(v)
    for v in range(1, V):  # again, against every other camera
        off[v], conf[v] = place(v, [w for w in range(V) if w != v])
    return off, conf


def _decide(c: np.ndarray, lags: np.ndarray, fps: float, name: str, source) -> tuple[float, float]:
    """The lag of least disagreement (seconds) and its confidence, the prominence of its
    valley: how much higher the next valley (a local minimum :data:`PEAK_WIDTH` seconds
    away or more) is, as a fraction of the curve's median above the best. Refused when
    below :data:`MIN_PROMINENCE`, or when the curve is flat (a static scene)."""
    if not np.isfinite(c).any():
        raise InputError(source, f"view {name}", f"people seen together with the other "
                         f"views in at least {MIN_OVERLAP} frames at some offset")  # fmt: skip
    w = max(2, int(round(PEAK_WIDTH * fps)))
    k = int(np.nanargmin(c))
    filled = np.where(np.isfinite(c), c, np.inf)
    local = [i for i in range(len(c)) if np.isfinite(c[i])
             and c[i] <= filled[max(0, i - w) : i + w + 1].min()]  # fmt: skip
    others = [c[i] for i in local if abs(i - k) > w]
    depth = float(np.nanmedian(c) - c[k])
    second = min(others) if others else float(np.nanmax(c))
    prominence = (second - c[k]) / depth if depth > 0 else 0.0
    if depth < MIN_DEPTH or prominence < MIN_PROMINENCE:
        raise InputError(
            source,
            f"view {name}",
            "enough motion to decide its time offset (a valley of disagreement at least "
            f"{MIN_DEPTH} px deep, the next valley {MIN_PROMINENCE:.2f} of that higher)",
            f"{c[k]:.1f} px at {int(lags[k])} frames, {depth:.1f} px under the median, the "
            f"next valley {second - c[k]:.1f} px higher",
        )
    return float(lags[k] / fps), float(min(1.0, prominence))


# --------------------------------------------------------------------------- the whole


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
    tracks = [link_people(kp[:, v]) for v in range(V)]
    if rig is None:
        speeds = [_trim(motion_speed(tr, f)) for tr, f in zip(tracks, fps, strict=True)]
        offsets, conf = coarse_offsets(speeds, fps, views, max_offset, source)
        offsets = np.round(offsets * fps) / fps  # whole frames of each camera
        return Sync(list(views), fps, offsets, conf, "motion")
    offsets, conf = scan_offsets(tracks, fps, rig, max_offset, views, source)
    if not fine:
        return Sync(list(views), fps, offsets, conf, "3d")
    off, resid = fine_offsets(tracks, fps, offsets, rig)
    return Sync(list(views), fps, off - off[0], conf, "3d-fine", resid)


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
    from dataclasses import replace

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
