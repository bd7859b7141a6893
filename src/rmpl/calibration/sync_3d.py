"""Synchronisation through a calibration: the offsets at which the views' people agree.

- **Agreement of two views at a relative offset.** For a pair of views (a, b) and a
  relative offset ``delta`` (seconds: b's clock ahead of a's by ``delta``), each of a's
  people in each of a's frames is matched to the person of b, at the same instant, whose
  joints lie nearest their epipolar lines (the symmetric distance in pixels, the median over
  joints, capped at :data:`EPIPOLAR_CAP`); b's 2D is interpolated between its two frames
  around the instant (people linked frame to frame). A frame's disagreement is the mean over
  its people; several people and their arbitrary order per frame need no association.
- **A frame against itself.** Each frame's disagreement is taken relative to its own median
  over the offsets tried (once by the frames of a, once by those of b, the two averaged),
  so frames that enter or leave the overlap as the offset changes (one with an extra,
  unmatched person, say) move the curve less.
- **Every camera at once.** The offsets minimise the sum over every pair of views of its
  curve, by coordinate descent over each camera's whole frames (up to ``max_offset``
  seconds), started from every camera in turn as the root (its pairs' best offsets) and
  kept from the start that ends lowest: no camera is placed against the first alone.
- **Decided or refused.** A camera's offset is decided when its next-best valleys (local
  minima :data:`PEAK_WIDTH` seconds away or more) and the curve's typical level (its
  median there) are worse than the best by at least :data:`MIN_Z` standard errors of the
  per-frame differences (the error widened for the frames' correlation in time, an AR(1)
  effective number of frames); offsets where no pair overlaps are not compared. The rule
  and its value were fixed before any recording was measured (three standard errors, the
  usual bar for "not noise"); the tests check it on synthetic sequences.
- **Fraction of a frame.** The same sum, sampled every 0.1 frame (of the fastest camera)
  within two frames of the slowest camera around the whole-frame answer, minimised over
  each camera's offset within one frame of the slowest camera (a fast camera's whole frame
  is pulled by the rounding of the slow ones) in steps of 0.05 of its own frames (every
  camera in turn until none moves), the minimum refined by a parabola. Its standard error is
  that of the slope there (per-frame slopes, the same effective number of frames) over
  the curvature: an error of half a frame or more means the whole frame is uncertain.

Shape glossary: ``T`` frames, ``V`` views, ``P`` people, ``J`` joints, ``S`` frames used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rmpl.errors import InputError

__all__ = ["EPIPOLAR_CAP", "MIN_Z", "PEAK_WIDTH", "agreement_offsets"]

#: A joint's epipolar distance is capped at this many pixels (a wrong match or joint).
EPIPOLAR_CAP = 30.0
#: A camera's best offset must beat its next valley by this many standard errors.
MIN_Z = 3.0
#: Two valleys closer than this (seconds) are one (a broad valley of slow motion).
PEAK_WIDTH = 0.2
#: Fewest frames of a pair that must overlap at an offset for it to count.
MIN_OVERLAP = 20
#: Judge the timing by each joint's epipolar distance minus its mean over the frames of
#: the same two people, so that a constant disagreement (calibration error, joints
#: defined differently in two views) does not pull the offset towards the lag at which
#: the motion happens to cancel it. Off: it needs long clean tracks, and with several
#: people (Shelf) the pairing of tracks is too unstable (``rmpl.benchmarks.sync
#: --bias-free`` measures it).
BIAS_FREE = False
#: At most this many frames of a view are compared (evenly spaced), to bound the work.
MAX_FRAMES = 600
#: Fine stage: span (frames of the slowest camera), the curves' step (frames of the
#: fastest) and the offsets' step (frames of each camera).
FINE_SPAN, FINE_GRID, FINE_STEP = 2.0, 0.1, 0.05


@dataclass(frozen=True)
class _View:
    norm: np.ndarray  # (T, P, J, 2) normalised image coordinates, NaN = missing
    nxt: np.ndarray  # (T, P) the same person's index in the next frame, -1 if none
    track: np.ndarray  # (T, P) each person's track (link_index), -1 where nobody is
    fps: float
    focal: float


@dataclass(frozen=True)
class _Curve:
    """One pair's disagreement per offset and frame of view a."""

    deltas: np.ndarray  # (N,) seconds
    frames: np.ndarray  # (N, S) pixels, NaN where not overlapping
    bframe: np.ndarray  # (N, S) int, view b's nearest frame at each, -1 outside

    def centred(self) -> np.ndarray:
        """Each frame relative to its own median over the offsets, (N, S)."""
        from rmpl.calibration.sync_base import _quiet

        with _quiet():
            return self.frames - np.nanmedian(self.frames, axis=0)

    def curve(self) -> np.ndarray:
        """Mean disagreement per offset, (N,), each frame of a and each frame of b taken
        relative to its own median over the offsets (the two averaged); NaN where too few
        frames overlap."""
        from rmpl.calibration.sync_base import _quiet

        a = self.centred()
        b = np.full((len(self.deltas), int(self.bframe.max()) + 2), np.nan)
        k, s = np.nonzero(self.bframe >= 0)
        b[k, self.bframe[k, s]] = self.frames[k, s]
        with _quiet():
            b = b - np.nanmedian(b, axis=0)
            mean_b = np.nanmean(np.where(self.bframe >= 0, b[np.arange(len(b))[:, None],
                                                             self.bframe], np.nan), -1)  # fmt: skip
            y = 0.5 * (np.nanmean(a, -1) + mean_b)
        return np.where(np.isfinite(a).sum(-1) >= MIN_OVERLAP, y, np.nan)

    def raw(self, delta: float) -> float:
        from rmpl.calibration.sync_base import _quiet

        k = int(np.argmin(np.abs(self.deltas - delta)))
        with _quiet():
            return float(np.nanmean(self.frames[k]))


def _views(keypoints: np.ndarray, fps: np.ndarray, rig) -> list[_View]:
    from rmpl.calibration.sync_base import _normalised, link_index

    out = []
    for v in range(keypoints.shape[1]):
        kp = keypoints[:, v]
        rows = link_index(kp)
        same = (rows[:-1, :, None] == rows[1:, None, :]) & (rows[:-1, :, None] >= 0)
        nxt = np.where(same.any(-1), same.argmax(-1), -1)
        nxt = np.concatenate([nxt, np.full((1, kp.shape[1]), -1)])
        focal = float(np.mean(np.diag(rig[v].K)[:2]))
        out.append(_View(_normalised(kp, rig[v]), nxt, rows, float(fps[v]), focal))
    return out


def _at(view: _View, frames: np.ndarray) -> np.ndarray:
    """The view's people at fractional frames (S,): (S, P, J, 2), linear between the two
    frames around each instant for a person linked in both (else the earlier frame held);
    NaN outside the recording."""
    T = len(view.norm)
    f0 = np.floor(frames + 1e-6).astype(int)
    a = frames - f0
    inside = (f0 >= 0) & (f0 < T) & ((a < 1e-6) | (f0 + 1 < T))
    i0 = np.clip(f0, 0, T - 1)
    x0 = view.norm[i0]
    if np.all(a < 1e-6):
        return np.where(inside[:, None, None, None], x0, np.nan)
    i1 = np.clip(f0 + 1, 0, T - 1)
    nxt = view.nxt[i0]  # (S, P)
    x1 = np.take_along_axis(view.norm[i1], np.maximum(nxt, 0)[..., None, None], axis=1)
    x1 = np.where((nxt >= 0)[..., None, None] & np.isfinite(x1), x1, x0)  # else held
    w = a[:, None, None, None]
    out = np.where(w < 1e-6, x0, (1 - w) * x0 + w * x1)
    return np.where(inside[:, None, None, None], out, np.nan)


def _essential(rig, a: int, b: int) -> np.ndarray:
    from rmpl.calibration.sync_base import _essential as ess

    return ess(rig, a, b)


def _homog(x: np.ndarray) -> np.ndarray:
    return np.concatenate([x, np.ones(x.shape[:-1] + (1,))], -1)


def _pair_curve(va: _View, vb: _View, E: np.ndarray, deltas: np.ndarray) -> _Curve:
    """The disagreement of views a and b (E: x_b^T E x_a = 0) at each offset ``deltas``
    (seconds, b's clock ahead of a's), per frame of a (at most :data:`MAX_FRAMES`)."""

    seen = np.flatnonzero(np.isfinite(va.norm).all(-1).any((-1, -2)))
    step = max(1, int(np.ceil(len(seen) / MAX_FRAMES))) if len(seen) else 1
    fa = np.arange(seen[0], seen[-1] + 1, step) if len(seen) else np.zeros(0, int)
    la = np.einsum("ij,...j->...i", E, _homog(va.norm[fa]))  # lines in b, (S, Pa, J, 3)
    na = np.linalg.norm(la[..., :2], axis=-1)  # (S, Pa, J)
    out = np.full((len(deltas), len(fa)), np.nan)
    bframe = np.full(out.shape, -1)
    Tb = len(vb.norm)
    for k, d in enumerate(deltas):
        fb = (fa / va.fps + d) * vb.fps
        use = (fb >= 0) & (fb <= Tb - 1)
        if use.sum() < MIN_OVERLAP:
            continue
        bframe[k, use] = np.round(fb[use]).astype(int)
        hb = _homog(_at(vb, fb[use]))  # (S', Pb, J, 3)
        nb = np.linalg.norm(np.einsum("ji,...j->...i", E, hb)[..., :2], axis=-1)
        num = np.einsum("sajk,sbjk->sabj", la[use], hb)  # (S', Pa, Pb, J)
        dist = 0.5 * (num / na[use][:, :, None] * vb.focal + num / nb[:, None] * va.focal)
        tb = vb.track[np.clip(np.floor(fb[use] + 1e-6).astype(int), 0, Tb - 1)]
        out[k, use] = _frame_disagreement(dist, va.track[fa[use]], tb)
    return _Curve(np.asarray(deltas, float), out, bframe)


def _frame_disagreement(dist: np.ndarray, ta: np.ndarray, tb: np.ndarray) -> np.ndarray:
    """Each frame's disagreement (S,) from the signed epipolar distances (S, Pa, Pb, J) of
    every pair of people: each of a's people matched to the b person of least median
    distance; with :data:`BIAS_FREE`, each joint's distance minus its mean over the frames
    of the same pair of tracks (``ta`` (S, Pa), ``tb`` (S, Pb)); the median over joints
    of the absolute (capped), the mean over people."""
    from rmpl.calibration.sync_base import _quiet

    with _quiet():
        per = np.nanmedian(np.minimum(np.abs(dist), EPIPOLAR_CAP), -1)  # (S, Pa, Pb)
    per = np.where(np.isfinite(per), per, np.inf)
    m = per.argmin(-1)  # (S, Pa)
    d = np.take_along_axis(dist, m[:, :, None, None], axis=2)[:, :, 0]  # (S, Pa, J)
    d = np.where(np.isfinite(per.min(-1))[..., None], d, np.nan)
    if BIAS_FREE:
        pair = np.where(ta >= 0, ta * (int(tb.max()) + 2) + np.take_along_axis(tb, m, 1), -1)
        d = _less_bias(d, pair)
    with _quiet():
        return np.nanmean(np.nanmedian(np.minimum(np.abs(d), EPIPOLAR_CAP), -1), -1)


def _less_bias(d: np.ndarray, group: np.ndarray) -> np.ndarray:
    """Signed distances (S, P, J) minus their mean over each group's entries (``group``
    (S, P), -1 = none), joint by joint; NaN where a group's joint has fewer than
    :data:`MIN_OVERLAP` entries (too few to know its bias)."""
    J = d.shape[-1]
    flat, g = d.reshape(-1, J), group.ravel()
    out = np.full_like(flat, np.nan)
    ok = np.flatnonzero(g >= 0)
    if not len(ok):
        return out.reshape(d.shape)
    _, inv = np.unique(g[ok], return_inverse=True)
    x = flat[ok]
    fin = np.isfinite(x)
    sums = np.zeros((inv.max() + 1, J))
    count = np.zeros((inv.max() + 1, J))
    np.add.at(sums, inv, np.where(fin, x, 0.0))
    np.add.at(count, inv, fin)
    mean = sums / np.maximum(count, 1)
    out[ok] = np.where(count[inv] >= MIN_OVERLAP, x - mean[inv], np.nan)
    return out.reshape(d.shape)


def _curves(views: list[_View], rig, deltas_of, desc: str) -> dict[tuple[int, int], _Curve]:
    """Every pair's curve (a progress bar per pair of views)."""
    from tqdm.auto import tqdm

    pairs = [(a, b) for a in range(len(views)) for b in range(a + 1, len(views))]
    return {(a, b): _pair_curve(views[a], views[b], _essential(rig, a, b), deltas_of(a, b))
            for a, b in tqdm(pairs, desc=desc, unit="pair", leave=False)}  # fmt: skip


class _Objective:
    """The sum over pairs of their centred curves, as a function of the offsets; a pair
    whose views do not overlap at an offset counts as its worst (no camera gains by
    leaving the others' time)."""

    def __init__(self, curves: dict[tuple[int, int], _Curve], V: int):
        self.V = V
        self.c = {}
        for key, cv in curves.items():
            y = cv.curve()
            worst = float(np.nanmax(y)) if np.isfinite(y).any() else 0.0
            self.c[key] = (cv.deltas, np.where(np.isfinite(y), y, worst))

    def pair(self, a: int, b: int, delta: np.ndarray) -> np.ndarray:
        x, y = self.c[(a, b)] if a < b else self.c[(b, a)]
        d = delta if a < b else -delta
        return np.interp(d, x, y)

    def profile(self, v: int, cand: np.ndarray, off: np.ndarray) -> np.ndarray:
        """The objective's terms that involve camera v, with v at each of ``cand``."""
        return sum(self.pair(w, v, cand - off[w]) for w in range(self.V) if w != v)

    def total(self, off: np.ndarray) -> float:
        return float(sum(self.pair(a, b, np.array([off[b] - off[a]]))[0]
                         for a, b in self.c))  # fmt: skip


def _descend(obj: _Objective, grids: list[np.ndarray], off: np.ndarray, sweeps: int):
    off = off.copy()
    for _ in range(sweeps):
        moved = False
        for v in range(1, obj.V):
            k = int(np.argmin(obj.profile(v, grids[v], off)))
            if grids[v][k] != off[v]:
                off[v], moved = grids[v][k], True
        if not moved:
            break
    return off


def _whole_frames(obj: _Objective, grids: list[np.ndarray], fps: np.ndarray) -> np.ndarray:
    """Offsets on each camera's grid of whole frames minimising the objective: coordinate
    descent from each camera as the root (every other at its best offset from the root)."""
    V = obj.V
    span = max(float(np.abs(g).max()) for g in grids)
    best, best_val = None, np.inf
    for root in range(V):
        start = np.zeros(V)
        for v in range(V):
            if v != root:
                rel = np.arange(-np.ceil(2 * span * fps[v]), np.ceil(2 * span * fps[v]) + 1)
                rel = rel / fps[v]  # v's clock ahead of the root's, whole frames of v
                start[v] = rel[int(np.argmin(obj.pair(root, v, rel)))]
        start = [g[int(np.argmin(np.abs(g - s)))] for g, s in zip(grids, start - start[0],
                                                                  strict=True)]  # fmt: skip
        off = _descend(obj, grids, np.array(start), sweeps=4 * V)
        val = obj.total(off)
        if val < best_val - 1e-12:
            best, best_val = off, val
    return best


def _var_of_sum(x: np.ndarray) -> float:
    """The variance of the sum of a per-frame series, its frames correlated in time as an
    AR(1) process (the lag-one autocorrelation, clipped to [0, 0.99])."""
    c = x - x.mean()
    den = float((c * c).sum())
    rho = min(max(float((c[1:] * c[:-1]).sum() / den) if den > 0 else 0.0, 0.0), 0.99)
    return len(x) * float(x.var(ddof=1)) * (1 + rho) / (1 - rho)


def _uncertainty(obj: _Objective, curves, off: np.ndarray, fps: np.ndarray) -> np.ndarray:
    """Each camera's standard error, frames: the error of its pairs' mean slope at the
    answer (per-frame slopes, :func:`_var_of_sum`) over the curvature of its profile
    (half a frame either side); inf where the profile is not convex there."""
    out = np.zeros(len(off))
    for v in range(1, len(off)):
        var = 0.0
        for (a, b), cv in curves.items():
            k = int(np.argmin(np.abs(cv.deltas - (off[b] - off[a]))))
            if v not in (a, b) or not 0 < k < len(cv.deltas) - 1:
                continue
            g = (cv.frames[k + 1] - cv.frames[k - 1]) / (cv.deltas[k + 1] - cv.deltas[k - 1])
            g = g[np.isfinite(g)]
            if len(g) >= MIN_OVERLAP:
                var += _var_of_sum(g) / len(g) ** 2
        h = 0.5 / fps[v]
        p = obj.profile(v, off[v] + np.array([-h, 0.0, h]), off)
        curv = (p[0] - 2 * p[1] + p[2]) / h**2
        out[v] = np.sqrt(var) / curv * fps[v] if curv > 0 and var > 0 else np.inf
    return out


def _z(curves, off: np.ndarray, v: int, other: float) -> float:
    """How many standard errors the per-frame disagreement of camera v's pairs is worse
    with v at ``other`` than at ``off[v]`` (AR(1) effective frames); NaN when no pair
    overlaps enough there to compare."""
    num, var, used = 0.0, 0.0, 0
    for (a, b), cv in curves.items():
        if v not in (a, b):
            continue
        alt = off.copy()
        alt[v] = other
        rows = [int(np.argmin(np.abs(cv.deltas - (o[b] - o[a])))) for o in (off, alt)]
        c = cv.centred()
        diff = c[rows[1]] - c[rows[0]]
        diff = diff[np.isfinite(diff)]
        if len(diff) < MIN_OVERLAP:
            continue
        num, used, var = num + float(diff.sum()), used + 1, var + _var_of_sum(diff)
    if not used:
        return np.nan  # no frames to compare there: not a competitor
    if var <= 0:
        return np.inf if num > 0 else 0.0
    return num / np.sqrt(var)


def _decide(obj, curves, grids, off, fps, views, source) -> np.ndarray:
    """Each camera's z (the module docstring); refuses the cameras below :data:`MIN_Z`."""
    V = len(off)
    z = np.full(V, np.inf)
    why = []
    for v in range(1, V):
        prof = obj.profile(v, grids[v], off)
        k = int(np.argmin(np.abs(grids[v] - off[v])))
        w = max(1, int(round(PEAK_WIDTH * fps[v])))
        far = np.abs(np.arange(len(prof)) - k) > w
        local = np.array([prof[i] <= prof[max(0, i - w) : i + w + 1].min()
                          for i in range(len(prof))])  # fmt: skip
        cand = np.flatnonzero(far & local)
        cand = list(cand[np.argsort(prof[cand])[:3]])
        if far.any():  # and the curve's typical level (a static scene has no valley)
            med = np.flatnonzero(far)
            cand.append(med[int(np.argmin(np.abs(prof[med] - np.median(prof[med]))))])
        zs = [_z(curves, off, v, grids[v][i]) for i in cand]
        zs = [x for x in zs if not np.isnan(x)]
        z[v] = min(zs) if zs else 0.0
        if not z[v] >= MIN_Z:
            why.append(f"{views[v]} ({z[v]:.1f})")
    if why:
        raise InputError(
            source,
            "motion",
            "enough motion of the people in view to decide every camera's time offset (its "
            f"best offset better than the next by {MIN_Z:.0f} standard errors)",
            "undecided: " + ", ".join(why),
        )
    return z


def _fine(views, rig, off: np.ndarray, fps: np.ndarray):
    """(offsets, residual px, uncertainty frames) to a fraction of a frame."""
    rate = float(np.max(fps))
    slow = float(np.min(fps))
    local = np.arange(-FINE_SPAN / slow, FINE_SPAN / slow + 1e-9, FINE_GRID / rate)
    curves = _curves(views, rig, lambda a, b: off[b] - off[a] + local, "sync: fraction")
    obj = _Objective(curves, len(off))
    grids = [np.array([0.0])]
    for v in range(1, len(off)):
        grids.append(off[v] + np.arange(-1 / slow, 1 / slow + 1e-9, FINE_STEP / fps[v]))
    out = _descend(obj, grids, off, sweeps=100)
    for v in range(1, len(off)):
        g = out[v] + np.array([-1.0, 0.0, 1.0]) * FINE_STEP / fps[v]
        p = obj.profile(v, g, out)
        den = p[0] - 2 * p[1] + p[2]
        if den > 0:
            out[v] += float(np.clip(0.5 * (p[0] - p[2]) / den, -1, 1)) * FINE_STEP / fps[v]
    resid = np.array([np.nanmean([cv.raw(out[b] - out[a]) for (a, b), cv in curves.items()
                                  if v in (a, b)]) for v in range(len(off))])  # fmt: skip
    return out, resid, _uncertainty(obj, curves, out, fps)


def agreement_offsets(
    keypoints: np.ndarray,
    fps: np.ndarray,
    rig,
    max_offset: float,
    views: list[str],
    source=None,
    fine: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each camera's offset (seconds, (V,), the first camera 0) at which the views agree.

    Args:
        keypoints: shape (T, V, P, J, 2), pixels, NaN = missing; each view's own frames.
        fps: each camera's frame rate, (V,).
        rig: the V calibrated cameras.
        max_offset: largest offset searched, seconds.
        fine: refine to a fraction of a frame (else whole frames of each camera).

    Returns:
        (offsets, confidence in [0, 1): z / (z + MIN_Z), the mean epipolar disagreement
        at the answer per camera, pixels, and each offset's standard error in frames of
        its camera, NaN without ``fine``).

    Raises:
        InputError: a camera whose offset the motion does not decide.
    """
    fps = np.asarray(fps, float)
    V = len(fps)
    vs = _views(np.asarray(keypoints, float), fps, rig)
    rate = float(np.max(fps))
    n = int(np.ceil(2 * max_offset * rate))
    deltas = np.arange(-n, n + 1) / rate
    curves = _curves(vs, rig, lambda a, b: deltas, "sync: whole frames")
    obj = _Objective(curves, V)
    grids = [np.array([0.0])] + [
        np.arange(-np.ceil(max_offset * f), np.ceil(max_offset * f) + 1) / f for f in fps[1:]
    ]
    off = _whole_frames(obj, grids, fps)
    z = _decide(obj, curves, grids, off, fps, views, source)
    conf = np.ones(V)
    conf[np.isfinite(z)] = z[np.isfinite(z)] / (z[np.isfinite(z)] + MIN_Z)
    if not fine:
        resid = np.array([np.nanmean([cv.raw(off[b] - off[a]) for (a, b), cv in curves.items()
                                      if v in (a, b)]) for v in range(V)])  # fmt: skip
        return off, conf, resid, np.full(V, np.nan)
    off, resid, err = _fine(vs, rig, off, fps)
    return off, conf, resid, err
