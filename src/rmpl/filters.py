"""Clean 3D trajectories over time: fill short gaps, remove outliers, low-pass filter.

Every function takes points of shape (T, *, C): ``T`` frames first, any leading
dimensions after it (usually ``P`` people and ``J`` joints), and ``C`` coordinates last
(3 for world points in metres; 2D keypoints in pixels work too). A point is missing when
its coordinates are NaN, all of them or none. Nothing is ever extrapolated and nothing is
filtered across a gap: each finite run of a trajectory is handled on its own, and a NaN
stays NaN unless :func:`fill_gaps` was asked to bridge it.

The usual order, as in Pose2Sim: :func:`hampel` (outliers -> NaN), :func:`fill_gaps`,
then :func:`butterworth` (or :func:`one_euro` for a causal, real-time friendly filter).

Defaults and where they come from:

- ``fill_gaps(max_gap=20)``: Pose2Sim interpolates gaps shorter than 20 frames; here
  gaps of up to ``max_gap`` frames are filled.
- ``hampel(window=7, n_sigma=3)``: Pose2Sim's Hampel window is 7 frames; 3 standard
  deviations is Hampel's classical threshold (Pearson's "3-sigma edit rule").
- ``butterworth(cutoff=6.0, order=4)``: Pose2Sim's default, a zero-phase 4th-order
  low-pass at 6 Hz, common in gait biomechanics (Winter). As in Pose2Sim, ``order`` is the
  order of the whole forward-backward filter: a Butterworth of order ``order / 2`` runs
  forwards then backwards, so the gain at ``cutoff`` is 1/2 (-6 dB), not 1/sqrt(2).
- ``one_euro(min_cutoff=1.0, beta=0.007, d_cutoff=1.0)``: the values commonly used with
  the 1-euro filter (Casiez, Roussel and Vogel, CHI 2012), tuned on pixel-scale pointing.
  ``beta`` multiplies a speed in metres per second here, so with metres it barely adapts
  and the filter acts as a 1 Hz first-order low-pass; raise ``beta`` (about 1) to cut the
  lag in fast movements.
"""

from __future__ import annotations

import numpy as np

from rmpl.errors import InputError

__all__ = ["fill_gaps", "butterworth", "one_euro", "hampel", "finite_runs"]

_MAD_TO_SIGMA = 1.4826  # MAD of a normal distribution times this is its standard deviation


def _check_points(points, field: str = "points") -> np.ndarray:
    """Points as a float array of shape (T, *, C) with all-or-none NaN per point."""
    try:
        x = np.array(points, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            None, field, "a numeric array of shape (T, *, C)", type(points).__name__
        ) from None
    if x.ndim < 2:
        raise InputError(None, field, "shape (T, *, C), e.g. (T, P, J, 3)", x.shape)
    if np.isinf(x).any():
        raise InputError(None, field, "finite coordinates or NaN for missing", "inf")
    nan = np.isnan(x)
    if (nan.any(-1) != nan.all(-1)).any():
        raise InputError(None, field, "every coordinate of a point NaN, or none", "partial NaN")
    return x


def _positive(value, field: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(None, field, "a positive number", value) from None
    if not np.isfinite(v) or v <= 0:
        raise InputError(None, field, "a positive number", value)
    return v


def _count(value, field: str, minimum: int) -> int:
    number = isinstance(value, int | float | np.integer | np.floating)
    whole = number and not isinstance(value, bool) and np.isfinite(value) and value == int(value)
    if not whole or value < minimum:
        raise InputError(None, field, f"an integer >= {minimum}", value)
    return int(value)


def finite_runs(ok: np.ndarray) -> list[tuple[int, int]]:
    """Start and stop (exclusive) of each run of True in a 1-D mask.

    >>> finite_runs(np.array([0, 1, 1, 0, 1], bool))
    [(1, 3), (4, 5)]
    """
    edges = np.diff(np.concatenate([[0], np.asarray(ok, np.int8), [0]]))
    return list(
        zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True)
    )


# --------------------------------------------------------------------------- gaps


def fill_gaps(
    points: np.ndarray, max_gap: int = 20, method: str = "linear"
) -> tuple[np.ndarray, np.ndarray]:
    """Interpolate the missing frames between two observations, up to ``max_gap`` long.

    A gap is filled only when it has an observed frame on both sides and at most
    ``max_gap`` missing frames; gaps at the start or end of a trajectory stay NaN.

    Args:
        points: shape (T, *, C), NaN where missing (e.g. (T, P, J, 3) metres).
        max_gap: longest run of missing frames to fill (Pose2Sim: 20).
        method: ``"linear"``, or ``"cubic"`` for a cubic spline through every observed
            frame of the trajectory (smoother, can overshoot on noisy data).

    Returns:
        ``(filled, interpolated)``: filled points, shape (T, *, C), and a mask of the
        points that were filled in, shape (T, *).

    >>> x = np.array([[0.0], [np.nan], [np.nan], [3.0], [np.nan]])
    >>> filled, mask = fill_gaps(x)
    >>> filled.ravel().tolist(), mask.tolist()
    ([0.0, 1.0, 2.0, 3.0, nan], [False, True, True, False, False])
    """
    x = _check_points(points)
    max_gap = _count(max_gap, "max_gap", 0)
    if method not in ("linear", "cubic"):
        raise InputError(None, "method", "'linear' or 'cubic'", method)
    T = x.shape[0]
    ok = ~np.isnan(x[..., 0])  # (T, *)
    frame = np.arange(T).reshape(T, *([1] * (ok.ndim - 1)))
    prev = np.maximum.accumulate(np.where(ok, frame, -1), axis=0)  # last observed frame <= t
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(ok, frame, T), 0), axis=0), 0)
    fill = ~ok & (prev >= 0) & (nxt < T) & (nxt - prev - 1 <= max_gap)
    out = x.copy()
    if not fill.any():
        return out, fill
    if method == "linear":
        p, n = np.clip(prev, 0, T - 1)[..., None], np.clip(nxt, 0, T - 1)[..., None]
        x0, x1 = np.take_along_axis(x, p, 0), np.take_along_axis(x, n, 0)
        w = (frame[..., None] - p) / np.maximum(n - p, 1)
        out[fill] = (x0 + w * (x1 - x0))[fill]
    else:
        _fill_cubic(x, fill, out)
    return out, fill


def _fill_cubic(x: np.ndarray, fill: np.ndarray, out: np.ndarray) -> None:
    """Cubic-spline values at the ``fill`` points, one trajectory at a time, into ``out``."""
    from scipy.interpolate import CubicSpline

    T, C = x.shape[0], x.shape[-1]
    xs, fs, os = x.reshape(T, -1, C), fill.reshape(T, -1), out.reshape(T, -1, C)
    for n in np.flatnonzero(fs.any(0)):  # only trajectories with something to fill
        seen = np.flatnonzero(~np.isnan(xs[:, n, 0]))
        todo = np.flatnonzero(fs[:, n])
        os[todo, n] = CubicSpline(seen, xs[seen, n], axis=0)(todo)


# --------------------------------------------------------------------------- filters


def _per_run(x: np.ndarray, fn) -> np.ndarray:
    """Apply ``fn`` (T', N', C) -> (T', N', C) to each finite run of every trajectory.

    Trajectories sharing the same missing frames are processed together, so a clean
    recording is one call per run, not one per joint.
    """
    T, C = x.shape[0], x.shape[-1]
    flat = x.reshape(T, -1, C)
    out = np.full_like(flat, np.nan)
    ok = ~np.isnan(flat[..., 0])  # (T, N)
    if ok.size == 0:
        return out.reshape(x.shape)
    patterns, group = np.unique(ok, axis=1, return_inverse=True)
    group = group.reshape(-1)
    for k in range(patterns.shape[1]):
        cols = np.flatnonzero(group == k)
        for a, b in finite_runs(patterns[:, k]):
            out[a:b, cols] = fn(flat[a:b, cols])
    return out.reshape(x.shape)


def _check_cutoff(fps: float, cutoff: float, field: str = "cutoff") -> tuple[float, float]:
    fps, cutoff = _positive(fps, "fps"), _positive(cutoff, field)
    if cutoff >= fps / 2:
        raise InputError(
            None, field, f"a frequency below Nyquist, fps / 2 = {fps / 2:g} Hz", cutoff
        )
    return fps, cutoff


def butterworth(points: np.ndarray, fps: float, cutoff: float = 6.0, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass, each finite run filtered on its own.

    Args:
        points: shape (T, *, C), NaN where missing.
        fps: frames per second.
        cutoff: cut-off frequency in Hz, below ``fps / 2`` (Pose2Sim: 6 Hz).
        order: order of the whole zero-phase filter, even (Pose2Sim: 4); a Butterworth of
            order ``order / 2`` runs forwards and backwards.

    Returns:
        Filtered points, shape (T, *, C), NaN exactly where the input is NaN. Runs are
        padded by odd reflection, shortened to fit short runs; single frames pass unchanged.

    >>> t = np.arange(200) / 100.0
    >>> x = np.sin(2 * np.pi * 1.0 * t)[:, None]  # 1 Hz passes a 6 Hz low-pass
    >>> bool(np.abs(butterworth(x, fps=100) - x)[20:-20].max() < 0.01)
    True
    """
    from scipy.signal import butter, sosfiltfilt

    x = _check_points(points)
    fps, cutoff = _check_cutoff(fps, cutoff)
    order = _count(order, "order", 2)
    if order % 2:
        raise InputError(None, "order", "an even order (two passes of order / 2)", order)
    sos = butter(order // 2, cutoff, btype="low", fs=fps, output="sos")
    full_pad = 3 * (2 * len(sos) + 1)  # scipy's default padding for this filter

    def run(seg: np.ndarray) -> np.ndarray:
        if len(seg) < 2:
            return seg
        return sosfiltfilt(sos, seg, axis=0, padtype="odd", padlen=min(full_pad, len(seg) - 1))

    return _per_run(x, run)


def one_euro(
    points: np.ndarray,
    fps: float,
    min_cutoff: float = 1.0,
    beta: float = 0.007,
    d_cutoff: float = 1.0,
) -> np.ndarray:
    """The 1-euro filter: a causal low-pass whose cut-off rises with speed.

    Each point is one 3D (or C-D) signal: its speed is the norm of its smoothed velocity,
    so the filter treats all coordinates alike, whatever the world axes. The filter
    restarts after every gap, from the first observed value.

    Args:
        points: shape (T, *, C), NaN where missing.
        fps: frames per second.
        min_cutoff: cut-off at rest, Hz; lower removes more jitter and adds lag.
        beta: cut-off increase per unit of speed (Hz per m/s for metres); raise it to cut
            lag in fast movements. See the module docstring for the defaults.
        d_cutoff: cut-off of the low-pass on the velocity, Hz.

    Returns:
        Filtered points, shape (T, *, C), NaN exactly where the input is NaN.

    >>> x = np.full((50, 3), 2.0)
    >>> bool(np.allclose(one_euro(x, fps=30), 2.0))
    True
    """
    x = _check_points(points)
    fps = _positive(fps, "fps")
    min_cutoff, d_cutoff = _positive(min_cutoff, "min_cutoff"), _positive(d_cutoff, "d_cutoff")
    beta = float(beta)
    if not np.isfinite(beta) or beta < 0:
        raise InputError(None, "beta", "a number >= 0", beta)

    def alpha(cutoff):  # smoothing factor of a first-order low-pass sampled at fps
        return 1.0 / (1.0 + fps / (2 * np.pi * cutoff))

    T, C = x.shape[0], x.shape[-1]
    flat = x.reshape(T, -1, C)
    out = np.full_like(flat, np.nan)
    est = np.full(flat.shape[1:], np.nan)  # filtered value of the previous frame, (N, C)
    vel = np.zeros(flat.shape[1:])  # filtered velocity, (N, C)
    a_d = alpha(d_cutoff)
    for t in range(T):
        obs = flat[t]
        seen = ~np.isnan(obs[:, 0])
        going = seen & ~np.isnan(est[:, 0])  # seen now and in the previous frame
        raw_vel = np.where(going[:, None], (obs - est) * fps, 0.0)
        vel = np.where(going[:, None], vel + a_d * (raw_vel - vel), 0.0)
        a = alpha(min_cutoff + beta * np.linalg.norm(vel, axis=-1))[:, None]
        est = np.where(going[:, None], est + a * (obs - est), obs)  # obs: start or NaN
        out[t] = est
    return out.reshape(x.shape)


def _nanmedian_last(a: np.ndarray) -> np.ndarray:
    """Median over the last axis ignoring NaN; NaN where all are NaN."""
    s = np.sort(a, axis=-1)  # NaN sorts last
    k = (~np.isnan(a)).sum(-1, keepdims=True)
    lo = np.take_along_axis(s, np.maximum((k - 1) // 2, 0), -1)
    hi = np.take_along_axis(s, np.maximum(k // 2, 0), -1)
    return np.where(k > 0, 0.5 * (lo + hi), np.nan)[..., 0]


def hampel(
    points: np.ndarray,
    window: int = 7,
    n_sigma: float = 3.0,
    *,
    min_deviation: float = 0.0,
    chunk: int = 4096,
) -> np.ndarray:
    """Hampel outlier filter: a point far from its neighbours' median becomes NaN.

    For every frame, the median and the median absolute deviation (MAD) of each coordinate
    are taken over a centred window of frames, ignoring NaN (the window is cut at the ends).
    A point is an outlier when any coordinate is more than ``n_sigma * 1.4826 * MAD`` from
    the median; outliers become NaN (fill them with :func:`fill_gaps`). Windows with fewer
    than 3 observed frames judge nothing. Where most of a window is identical the MAD is 0
    and any different value is an outlier; ``min_deviation`` sets a floor for such data.

    Args:
        points: shape (T, *, C), NaN where missing.
        window: odd number of frames in the window (Pose2Sim: 7).
        n_sigma: threshold in robust standard deviations (classical value: 3).
        min_deviation: deviations up to this never count as outliers, in the units of the
            points (e.g. 0.01 m); 0 by default.
        chunk: frames processed at once, to bound memory on long recordings.

    Returns:
        Points, shape (T, *, C), with outliers set to NaN.

    >>> x = np.zeros((9, 1)); x[4] = 5.0; x[::2] += 0.01
    >>> np.flatnonzero(np.isnan(hampel(x)[:, 0])).tolist()
    [4]
    """
    from numpy.lib.stride_tricks import sliding_window_view

    x = _check_points(points)
    window = _count(window, "window", 3)
    if window % 2 == 0:
        raise InputError(None, "window", "an odd number of frames (centred window)", window)
    n_sigma = _positive(n_sigma, "n_sigma")
    min_deviation = float(min_deviation)
    if not np.isfinite(min_deviation) or min_deviation < 0:
        raise InputError(None, "min_deviation", "a number >= 0", min_deviation)
    chunk = _count(chunk, "chunk", 1)
    half = window // 2
    T = x.shape[0]
    pad = np.full((half, *x.shape[1:]), np.nan)
    padded = np.concatenate([pad, x, pad])
    out = x.copy()
    for a in range(0, T, chunk):
        b = min(a + chunk, T)
        win = sliding_window_view(padded[a : b + 2 * half], window, axis=0)  # (b-a, *, C, W)
        med = _nanmedian_last(win)
        mad = _nanmedian_last(np.abs(win - med[..., None]))
        enough = (~np.isnan(win)).sum(-1) >= 3
        dev = np.abs(x[a:b] - med)
        limit = np.maximum(n_sigma * _MAD_TO_SIGMA * mad, min_deviation)
        outlier = (enough & (dev > limit)).any(-1)  # (b-a, *)
        out[a:b][outlier] = np.nan
    return out
