"""One calibrated camera's depth cues: the floor, body size and time.

One view gives rays, not where along them the person stands. The per-frame lifter
(:class:`rmpl.inference.Lifter`) still answers with a fair shape, but its distance from the
camera is off by about 20%. With camera centre ``C``, every scaled pose ``C + s (X - C)``
projects like ``X``: a one-parameter family per frame. Three cues choose ``s``
(:class:`MonocularConfig` ``cues``):

- **floor**: a standing or walking person's lowest seen ankle rests
  :data:`~rmpl.geometry.floor.ANKLE_HEIGHT` above the floor. Its 2D ray meets that level at
  one point, which fixes ``s`` (:func:`floor_log_scale`). Contact is not assumed when the
  ankle is unseen (score below ``ankle_score``), when the lifter's pose is lying (trunk more
  than ``lying_angle`` from vertical) or seated / squatting (both thighs more than
  ``seated_angle`` from vertical) (:func:`may_touch_floor`), when the ray barely descends,
  and, with time, when at the track's depth the lowest ankle would be more than
  ``airborne`` above its resting height (a jump, a step, a raised foot).
- **size**: bone lengths give a stature proxy (:func:`stature_proxy`); adult stature is
  about 1.70 m +- 0.09 m, so ``s = stature / proxy`` (:func:`size_log_scale`).
- **time** (whole tracks): bone lengths are constant over a track, so the track's stature
  is estimated once, robustly, from its floor-contact frames (shrunk to the adult prior);
  depth changes smoothly, so the per-frame log depths are smoothed along the track
  (:func:`track_log_depth`) before the usual filters (:func:`rmpl.pipeline.runner.smooth`).

:mod:`rmpl.pipeline.monocular` lifts one view's people and applies them.

Every per-frame estimate is a log-scale with a standard deviation from a stated noise model
(:class:`MonocularConfig`); cues combine by inverse variance. The uncertainty written to
:attr:`rmpl.io.poses.Poses3D.uncertainty` is the 50% radius of the depth error along each
joint's ray implied by that standard deviation (``0.674 sigma |X_j - C|``); it leaves out the
lifter's shape error.

The lifter's poses are COCO-17 or HALPE-26 (its first 17 joints are COCO-17): the cues read
COCO-17 joints by their index (ankles, knees, hips, shoulders), so they see the same joints
in both, and the chosen depth moves every joint (head top, neck, mid-hip and feet too).

Shape glossary: ``T`` frames, ``N`` people in one frame, ``P`` tracks, ``J`` joints (COCO-17,
or the lifter's joint set where said).
Units: metres, seconds; scales are dimensionless, "log" means natural logarithm.
"""

from __future__ import annotations

import logging
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.floor import ANKLE_HEIGHT, Floor, signed_distance
from rmpl.skeleton import COCO17

__all__ = [
    "CONVENTION_FLOOR_SD",
    "CUES",
    "FLOOR_MODEL_LIFTER_SD",
    "RADIUS_50_1D",
    "FrameCues",
    "MonocularConfig",
    "TrackDepth",
    "floor_from_poses",
    "floor_log_scale",
    "frame_cues",
    "may_touch_floor",
    "per_frame_log_scale",
    "size_log_scale",
    "stature_proxy",
    "track_log_depth",
]

log = logging.getLogger(__name__)

CUES = ("floor", "size", "time")
#: The one-view log-depth error of a model that reads the floor (``lifter_sd`` of
#: :meth:`MonocularConfig.for_model`): the robust standard deviation (1.4826 MAD) of the
#: shipped ``floor26``'s log(estimated / true distance) of the mid-hip on held-out renders
#: with a real detector, one view, the floor given (``rmpl.benchmarks.floor_select``;
#: docs/results.md, "One camera"). The tails are heavier (plain sd 0.124).
FLOOR_MODEL_LIFTER_SD = 0.033
#: The floor error assumed when the floor is the calibration's convention (its origin on the
#: floor), metres: a guess, not a measurement (Shelf's z = 0 is 9 cm off, a Qualisys L-frame's
#: about 0). It widens the uncertainty of a floor-reading model's depth by this / the
#: camera's height (the depth itself is unchanged).
CONVENTION_FLOOR_SD = 0.05
#: (shoulder height - ankle height) / stature for adults: 0.818 - 0.039 (Winter's segment
#: ratios); shin + thigh + trunk (mid-hip to mid-shoulder) spans it.
STATURE_RATIO = 0.779
_MIN_PROXY = 1e-3  # metres: below this a pose has collapsed to a point (stature_proxy)
#: The 50% radius of a one-dimensional normal error, in standard deviations.
RADIUS_50_1D = 0.674

_J = {name: COCO17.index(name) for name in COCO17.joints}  # the first 17 of HALPE-26 too
_ANKLES = [_J["left_ankle"], _J["right_ankle"]]
HIPS = [_J["left_hip"], _J["right_hip"]]


@dataclass(frozen=True)
class MonocularConfig:
    """How one view's depth is chosen. Every constant is set from anthropometry or from the
    synthetic scenes (see docs/results.md), never from a benchmark.

    Attributes:
        cues: any of "floor", "size", "time".
        contact_height: ankle joint centre above the floor when standing, metres.
        contact_sd: spread of the stance ankle height over a step (heel strike to heel
            rise, a flat or slightly lifted heel), metres.
        ray_sd: angular error of a 2D ankle (a few pixels at typical focal lengths), rad.
        shape_sd: error of the lifter's ankle relative to the rest of its pose, as a log
            scale (synthetic held-out scenes: median |error| 0.032 of the floor scale
            against the best scale, i.e. sd 0.045 + the terms above).
        min_camera_height: the camera must be at least this far above the ankle resting
            level for the floor cue, metres.
        ankle_score: a 2D ankle below this confidence is not used for contact.
        lying_angle: trunk more than this from vertical: lying, no contact, degrees.
        seated_angle: both thighs more than this from vertical: seated or squatting, no
            contact, degrees.
        stature: prior adult stature, metres (pooled adult men and women).
        stature_sd: its standard deviation, metres.
        stature_range: a track whose floor-implied stature falls outside this range
            (metres) is not on this floor (a stage, a stool, a wrong floor): its floor
            cue is dropped.
        size_sd: per-frame error of the size cue in one view, log (synthetic held-out
            scenes: sd 0.24 with heavy tails, median |error| 0.10; 0.20 is used).
        lifter_sd: error of the lifter's own depth in one view, log (synthetic: sd 0.20,
            median |error| 0.10); the lifter's depth is always a weak cue, and the answer
            when no other cue applies.
        airborne: with time, the lowest ankle more than this above its resting height
            at the track's depth means no contact (a jump), metres.
        window: time window of the contact test and of the depth smoother, seconds.
        min_contact_frames: floor-contact frames a track needs for its own stature.
    """

    cues: tuple[str, ...] = CUES
    contact_height: float = ANKLE_HEIGHT
    contact_sd: float = 0.03
    ray_sd: float = 0.005
    shape_sd: float = 0.045
    min_camera_height: float = 0.2
    ankle_score: float = 0.3
    lying_angle: float = 60.0
    seated_angle: float = 60.0
    stature: float = 1.70
    stature_sd: float = 0.09
    stature_range: tuple[float, float] = (1.45, 2.05)
    size_sd: float = 0.20
    lifter_sd: float = 0.20
    airborne: float = 0.15
    window: float = 2.0
    min_contact_frames: int = 5

    def __post_init__(self) -> None:
        bad = [c for c in self.cues if c not in CUES]
        if bad:
            raise ValueError(f"cues must be among {CUES}, got {bad}")
        positive = {
            "contact_sd": self.contact_sd, "ray_sd": self.ray_sd, "stature": self.stature,
            "stature_sd": self.stature_sd, "size_sd": self.size_sd,
            "lifter_sd": self.lifter_sd, "airborne": self.airborne, "window": self.window,
        }  # fmt: skip
        for name, value in positive.items():
            if not value > 0:
                raise ValueError(f"{name} must be > 0, got {value}")
        lo, hi = self.stature_range
        if not 0 < lo < self.stature < hi:
            raise ValueError(f"stature_range must bracket stature, got {self.stature_range}")

    @classmethod
    def from_cues(cls, text: str, **overrides) -> MonocularConfig:
        """``"floor+size+time"`` (any subset, joined by +; "none": the lifter's own depth)
        -> a config with those cues."""
        cues = tuple(c.strip() for c in text.split("+") if c.strip())
        if cues == ("none",):
            return cls(cues=(), **overrides)
        bad = [c for c in cues if c not in CUES]
        if bad or not cues:
            raise InputError(None, "cues", f"some of {', '.join(CUES)} joined by +, or none", text)
        return cls(cues=cues, **overrides)

    @classmethod
    def for_model(cls, model: str, floor_known: bool = True) -> MonocularConfig:
        """The cues ``rmpl run`` uses with a per-frame model: all three; for a model that
        reads the floor (:attr:`rmpl.inference.Lifter.reads_floor`) and a known floor, time
        alone, with that model's one-view depth error (:data:`FLOOR_MODEL_LIFTER_SD`): its
        depth already uses the floor and its learnt body sizes; without a floor its depth is
        no better than another model's, so the size prior and time, as before (chosen on
        held-out MHP sequences, docs/results.md)."""
        from rmpl.inference import checkpoint_reads_floor

        if checkpoint_reads_floor(model):
            if floor_known:
                return cls(cues=("time",), lifter_sd=FLOOR_MODEL_LIFTER_SD)
            return cls(cues=("size", "time"))
        return cls()


# --------------------------------------------------------------------------- per-pose math


def stature_proxy(points: np.ndarray) -> np.ndarray:
    """Stature from bone lengths, metres: (shin + thigh + trunk) / 0.779, shape (*,).

    Shin and thigh are averaged over the sides that are finite; trunk is mid-hip to
    mid-shoulder. Bone lengths do not depend on posture, so the proxy is the same standing,
    seated or lying. NaN when a bone is missing on both sides, or when the bones add up to
    less than a millimetre (a collapsed pose: no size to read).

    Args:
        points: COCO-17 joints (*, 17, 3), metres.

    >>> x = np.zeros((17, 3))
    >>> x[[15, 16], 2], x[[13, 14], 2], x[[11, 12], 2], x[[5, 6], 2] = 0.07, 0.5, 0.9, 1.4
    >>> round(float(stature_proxy(x)), 3)  # 0.43 + 0.40 + 0.50 = 1.33 m of 0.779 stature
    1.707
    """
    x = np.asarray(points, float)

    def bone(a: str, b: str) -> np.ndarray:
        return np.linalg.norm(x[..., _J[a], :] - x[..., _J[b], :], axis=-1)

    with np.errstate(invalid="ignore"), _quiet():
        shin = np.nanmean(np.stack([bone("left_knee", "left_ankle"),
                                    bone("right_knee", "right_ankle")]), 0)  # fmt: skip
        thigh = np.nanmean(np.stack([bone("left_hip", "left_knee"),
                                     bone("right_hip", "right_knee")]), 0)  # fmt: skip
    shoulders = x[..., [_J["left_shoulder"], _J["right_shoulder"]], :].mean(-2)
    trunk = np.linalg.norm(shoulders - x[..., HIPS, :].mean(-2), axis=-1)
    proxy = (shin + thigh + trunk) / STATURE_RATIO
    return np.where(proxy > _MIN_PROXY, proxy, np.nan)  # a collapsed pose has no size


@contextmanager
def _quiet():
    """Silence numpy's "mean of empty slice" warnings (all-NaN rows stay NaN)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


def _angle_from(v: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Angle (degrees) of vectors (*, 3) from the up direction (3,), ignoring the sign."""
    n = np.linalg.norm(v, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.abs(v @ up) / n
    return np.degrees(np.arccos(np.clip(c, 0, 1)))


def may_touch_floor(points: np.ndarray, up: np.ndarray, config: MonocularConfig) -> np.ndarray:
    """Whether a pose's shape allows floor contact: not lying, not seated, shape (*,).

    Lying: the trunk (mid-hip to mid-shoulder) more than ``lying_angle`` from vertical.
    Seated or squatting: both thighs more than ``seated_angle`` from vertical. Both tests
    use only directions, so they do not depend on the pose's scale.

    Args:
        points: COCO-17 joints (*, 17, 3), metres. up: (3,) unit vector.
    """
    x = np.asarray(points, float)
    shoulders = x[..., [_J["left_shoulder"], _J["right_shoulder"]], :].mean(-2)
    trunk = _angle_from(shoulders - x[..., HIPS, :].mean(-2), up)
    thighs = [
        _angle_from(x[..., _J[f"{s}_knee"], :] - x[..., _J[f"{s}_hip"], :], up)
        for s in ("left", "right")
    ]
    lying = trunk > config.lying_angle
    seated = (thighs[0] > config.seated_angle) & (thighs[1] > config.seated_angle)
    return ~lying & ~seated


def floor_log_scale(
    points: np.ndarray,
    rays: np.ndarray,
    scores: np.ndarray,
    center: np.ndarray,
    floor: Floor,
    config: MonocularConfig,
) -> tuple[np.ndarray, np.ndarray]:
    """The scale that stands the lowest seen ankle on the floor, per pose.

    The ankle the lifter puts lowest among those seen (score >= ``ankle_score``) is
    assumed to rest ``contact_height`` above the floor: its 2D ray meets that level at
    ``P``, and ``s`` brings the lifter's ankle nearest to ``P`` along the scaled family
    ``C + s (X - C)``. Its standard deviation (log) combines ``contact_sd / (camera height
    above the resting level)``, ``ray_sd / tan(ray declination)`` and ``shape_sd``.

    Args:
        points: lifter poses (N, 17, 3), metres. rays: the view's rays (N, 17, 6).
        scores: (N, 17). center: the camera centre (3,).

    Returns:
        log s (N,) and its standard deviation (N,); NaN where no ankle is usable, the
        camera is less than ``min_camera_height`` above the resting level, or the ray
        does not descend by at least 2 degrees.
    """
    x = np.asarray(points, float)
    n, c = floor.n, config.contact_height
    seen = (scores[:, _ANKLES] >= config.ankle_score) & np.isfinite(x[:, _ANKLES]).all(-1)
    heights = np.where(seen, signed_distance(x[:, _ANKLES], floor), np.inf)
    pick = np.argmin(heights, axis=1)  # (N,) the lower seen ankle
    rows = np.arange(len(x))
    ankle = np.asarray(_ANKLES)[pick]
    u = rays[rows, ankle, 3:]  # (N, 3) unit direction of its 2D ray
    h_cam = float(signed_distance(center, floor)) - c  # camera above the resting level
    descent = -(u @ n)  # sin of the ray's declination
    with np.errstate(invalid="ignore", divide="ignore"):
        lam = h_cam / descent  # distance along the ray to the resting level
        target = center + lam[:, None] * u  # (N, 3)
        d = x[rows, ankle] - center
        s = ((target - center) * d).sum(-1) / (d * d).sum(-1)
        tan = descent / np.sqrt(np.clip(1 - descent**2, 1e-12, None))
        sd = np.sqrt(
            (config.contact_sd / h_cam) ** 2 + (config.ray_sd / tan) ** 2 + config.shape_sd**2
        )
    ok = seen.any(1) & (descent > np.sin(np.radians(2.0))) & (s > 0)
    ok &= h_cam >= config.min_camera_height
    return np.where(ok, np.log(np.where(ok, s, 1.0)), np.nan), np.where(ok, sd, np.nan)


def size_log_scale(points: np.ndarray, stature: float) -> np.ndarray:
    """log of the scale that gives a pose (*, 17, 3) the stature proxy ``stature`` (m)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.log(stature / stature_proxy(points))


def _combine(values: list[np.ndarray], sds: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Inverse-variance mean of estimates (each (*,), NaN = absent): mean and sd (*,)."""
    v, s = np.stack(values), np.stack(sds)
    w = np.where(np.isfinite(v) & np.isfinite(s), 1.0 / np.square(s), 0.0)
    total = w.sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (w * np.nan_to_num(v)).sum(0) / total
        sd = 1.0 / np.sqrt(total)
    return np.where(total > 0, mean, np.nan), np.where(total > 0, sd, np.nan)


def scale_about(points: np.ndarray, center: np.ndarray, log_s: np.ndarray) -> np.ndarray:
    """``C + s (X - C)`` for poses (*, J, 3) and log-scales (*,)."""
    return center + np.exp(log_s)[..., None, None] * (points - center)


@dataclass
class FrameCues:
    """The per-pose cue estimates of :func:`frame_cues` (all shape (N,))."""

    floor: np.ndarray  # log s from the floor, NaN where it does not apply
    floor_sd: np.ndarray
    proxy: np.ndarray  # the lifter's stature proxy, metres
    upright: np.ndarray  # bool: the shape allows floor contact


def frame_cues(points, rays, scores, center, floor: Floor | None, up, config) -> FrameCues:
    """The floor and size cues of lifter poses (N, 17, 3) with their rays (N, 17, 6)."""
    N = len(points)
    upright = may_touch_floor(points, up, config)
    if floor is None or "floor" not in config.cues:
        f, fsd = np.full(N, np.nan), np.full(N, np.nan)
    else:
        f, fsd = floor_log_scale(points, rays, scores, center, floor, config)
        f, fsd = np.where(upright, f, np.nan), np.where(upright, fsd, np.nan)
    return FrameCues(f, fsd, stature_proxy(points), upright)


def per_frame_log_scale(cues: FrameCues, config: MonocularConfig):
    """Without time: combine the floor cue with the adult size prior, per pose.

    A single frame cannot tell a jump from a stance (the size cue is too coarse: about 10%
    per frame), so contact is assumed whenever the shape allows it and an ankle is seen.
    The lifter's own depth (log s = 0, ``lifter_sd``) is always a third, weak estimate.

    Returns:
        log s (N,) and its standard deviation (N,).
    """
    N = len(cues.floor)
    if "size" in config.cues:
        size = np.log(config.stature / cues.proxy)
        size_sd = np.full(N, np.hypot(config.stature_sd / config.stature, config.size_sd))
    else:
        size, size_sd = np.full(N, np.nan), np.full(N, np.nan)
    floor = cues.floor
    own, own_sd = np.zeros(N), np.full(N, config.lifter_sd)  # the lifter's own depth
    return _combine([floor, size, own], [cues.floor_sd, size_sd, own_sd])


def floor_from_poses(
    points: np.ndarray, up: np.ndarray | None = None, config: MonocularConfig | None = None
) -> Floor:
    """The floor under multi-view 3D poses of the same rig (triangulated or lifted).

    The lower ankle of every pose whose shape allows contact (:func:`may_touch_floor`) is a
    contact point; :func:`rmpl.geometry.floor.fit_floor` puts the floor ``contact_height``
    below their median height.

    Args:
        points: COCO-17 poses (..., 17, 3) metres, NaN = missing (e.g. (T, P, 17, 3)), or
            HALPE-26 ones (..., 26, 3) (their first 17 joints are used).
        up: the world up direction (3,), e.g. :func:`rmpl.inference.estimate_up` of the rig;
            None: the median trunk direction (mid-hip to mid-shoulder) of the poses, people
            being mostly upright. The floor's normal is refitted to the ankles when they
            spread over the floor (:func:`rmpl.geometry.floor.fit_floor`).

    Raises:
        InputError: fewer than 10 usable poses.
    """
    from rmpl.geometry.floor import fit_floor

    cfg = config or MonocularConfig()
    x = np.asarray(points, float)[..., : COCO17.num_joints, :].reshape(-1, COCO17.num_joints, 3)
    if up is None:
        shoulders = x[:, [_J["left_shoulder"], _J["right_shoulder"]]].mean(1)
        trunk = shoulders - x[:, HIPS].mean(1)
        trunk = trunk[np.isfinite(trunk).all(-1)]
        if not len(trunk):
            raise InputError(None, "floor", "poses with hips and shoulders to find up", 0)
        up = np.median(trunk / np.linalg.norm(trunk, axis=-1, keepdims=True), axis=0)
    u = np.asarray(up, float) / np.linalg.norm(up)
    ankles = x[:, _ANKLES]  # (N, 2, 3)
    with np.errstate(invalid="ignore"):
        h = np.where(np.isfinite(ankles).all(-1), ankles @ u, np.inf)
    low = ankles[np.arange(len(x)), np.argmin(h, axis=1)]  # (N, 3) the lower ankle
    keep = may_touch_floor(x, u, cfg) & np.isfinite(low).all(-1)
    return fit_floor(low[keep], u, cfg.contact_height)


# --------------------------------------------------------------------------- whole tracks


def _windowed(values: np.ndarray, times: np.ndarray, half: float, fn) -> np.ndarray:
    """``fn`` of the finite values within ``half`` seconds of each time, shape (T,)."""
    out = np.full(len(values), np.nan)
    ok = np.isfinite(values)
    for i, t in enumerate(times):
        sel = ok & (np.abs(times - t) <= half)
        if sel.any():
            out[i] = fn(values[sel], times[sel] - t)
    return out


def _local_linear(values, sds, times, half: float, iterations: int = 2) -> np.ndarray:
    """A robust weighted local-linear fit of noisy observations, at each time.

    Observations are (value, sd, time) triples; each fit weighs them by a tricube kernel of
    half-width ``half`` seconds and ``1 / sd^2``, then (``iterations`` times, as LOWESS
    does) by Tukey's bisquare of their standardised residual (c = 4.685), so a heavy tail
    of one cue does not pull the depth.

    Args:
        values, sds: (K, T) K estimates per frame (NaN = absent). times: (T,) seconds.

    Returns:
        The fitted value at each time (T,), NaN where no observation is within ``half``.
    """
    K, T = values.shape
    v, sd = values.ravel(), sds.ravel()
    t = np.broadcast_to(times, (K, T)).ravel()
    ok = np.isfinite(v) & np.isfinite(sd) & (sd > 0)
    v, sd, t = v[ok], sd[ok], t[ok]
    order = np.argsort(t, kind="stable")
    v, sd, t = v[order], sd[order], t[order]
    robust = np.ones(len(v))
    out = np.full(T, np.nan)
    for it in range(iterations + 1):
        fit_at_obs = np.full(len(v), np.nan) if it < iterations else None
        at = times if it == iterations else t
        lo = np.searchsorted(t, at - half, "left")
        hi = np.searchsorted(t, at + half, "right")
        fits = np.full(len(at), np.nan)
        for i, (a, b) in enumerate(zip(lo, hi, strict=True)):
            dt = t[a:b] - at[i]
            w = np.clip(1 - np.abs(dt / half) ** 3, 0, None) ** 3 / sd[a:b] ** 2 * robust[a:b]
            if not (w > 0).any():
                continue
            sw, swt, swv = w.sum(), (w * dt).sum(), (w * v[a:b]).sum()
            swtt, swtv = (w * dt * dt).sum(), (w * dt * v[a:b]).sum()
            det = sw * swtt - swt**2
            fits[i] = (swtt * swv - swt * swtv) / det if det > 1e-12 * sw * sw else swv / sw
        if it == iterations:
            out = fits
        else:
            fit_at_obs = fits
            z = (v - fit_at_obs) / sd / 4.685
            robust = np.where(np.abs(z) < 1, (1 - z**2) ** 2, 0.0)
            robust = np.where(np.isfinite(z), robust, 1.0)
    return out


@dataclass
class TrackDepth:
    """What :func:`track_log_depth` found for one track.

    Attributes:
        log_depth: smoothed log distance of the lifter's root from the camera (T,).
        sd: standard deviation of the per-frame estimate before smoothing, log (T,).
        contact: frames whose floor cue was used (T,) bool.
        stature: the track's stature, metres (the prior when it had too few contacts).
        stature_sd: its standard deviation, metres.
        floor_dropped: the track's floor-implied stature was implausible.
    """

    log_depth: np.ndarray
    sd: np.ndarray
    contact: np.ndarray
    stature: float
    stature_sd: float
    floor_dropped: bool = False


def track_log_depth(
    points: np.ndarray,
    cues: FrameCues,
    center: np.ndarray,
    floor: Floor | None,
    times: np.ndarray,
    config: MonocularConfig,
) -> TrackDepth:
    """The depth of one track over time, from its frames' floor and size cues.

    1. Contact test: the running median (``window``) of the floor-implied log depths is
       the track's depth; a frame whose lowest ankle would then be more than ``airborne``
       from its resting height is not in contact.
    2. The track's stature: the median over contact frames of (floor scale x the lifter's
       stature proxy), one independent sample per second, shrunk to the adult prior
       ("size" cue); outside ``stature_range`` the floor is dropped for the track. Without
       enough contact frames it is the prior ("size") or unknown.
    3. The floor cue (contact frames), the size cue with the track's stature and the
       lifter's own depth (``lifter_sd``) of every frame go through one robust weighted
       local-linear smoother over ``window`` (inverse-variance weights, bisquare
       reweighting of outliers).

    Args:
        points: the track's lifter poses (T, 17, 3), NaN where absent.
        cues: its :func:`frame_cues` (each (T,)).
        center: the camera centre (3,). times: (T,) seconds.

    Returns:
        :class:`TrackDepth` (log depths of the lifter's root, i.e. ``log s + log r``).
    """
    T = len(points)
    root = np.nanmean(points[:, HIPS], axis=1) if T else np.zeros((0, 3))
    log_r = np.log(np.linalg.norm(root - center, axis=-1))  # the lifter's own root distance
    half = config.window / 2
    floor_depth = cues.floor + log_r
    contact = _contact(floor_depth, log_r, points, center, floor, times, config)
    stature, stature_sd, dropped = _track_stature(cues, contact, times, config)
    if dropped:
        contact[:] = False
    own_stature = contact.sum() >= config.min_contact_frames and not dropped
    if "size" in config.cues or own_stature:  # the track's stature, or the adult prior
        size = np.log(stature / cues.proxy) + log_r
        size_sd = np.full(T, np.hypot(stature_sd, config.size_sd))
    else:
        size, size_sd = np.full(T, np.nan), np.full(T, np.nan)
    floor_depth = np.where(contact, floor_depth, np.nan)
    own_sd = np.full(T, config.lifter_sd)  # the lifter's own depth: a weak estimate
    estimates = np.stack([floor_depth, size, log_r])  # (3, T)
    sds = np.stack([cues.floor_sd, size_sd, own_sd])
    per_frame, sd = _combine(list(estimates), list(sds))
    smooth = _local_linear(estimates, sds, times, half)
    smooth = np.where(np.isfinite(smooth), smooth, per_frame)
    return TrackDepth(smooth, sd, contact, stature, stature * stature_sd, dropped)


def _contact(floor_depth, log_r, points, center, floor: Floor | None, times, config):
    """:func:`track_log_depth`'s step 1: the frames in floor contact (T,) bool."""
    half = config.window / 2
    contact = np.isfinite(floor_depth)
    if contact.any() and floor is not None:
        median = _windowed(floor_depth, times, half, lambda v, _: np.median(v))
        s = np.exp(median - log_r)
        ankles = np.where(contact[:, None], signed_distance(points[:, _ANKLES], floor), np.nan)
        at_median = float(signed_distance(center, floor)) + s[:, None] * (
            ankles - float(signed_distance(center, floor))
        )  # the ankles' heights with the track's depth: h_C + s (h - h_C)
        with _quiet():
            lowest = np.nanmin(at_median, axis=1)
        contact &= np.abs(lowest - config.contact_height) <= config.airborne
    return contact


def _track_stature(cues: FrameCues, contact, times, config) -> tuple[float, float, bool]:
    """:func:`track_log_depth`'s step 2: the track's stature and its sd (log), and whether
    its floor is dropped (the floor-implied stature outside ``stature_range``)."""
    prior_sd = config.stature_sd / config.stature  # log
    stature, stature_sd, dropped = config.stature, prior_sd, False
    if contact.sum() < config.min_contact_frames:
        return stature, stature_sd, dropped
    implied = cues.floor[contact] + np.log(cues.proxy[contact])  # log stature per frame
    implied = implied[np.isfinite(implied)]
    if len(implied) < config.min_contact_frames:
        return stature, stature_sd, dropped
    mid = float(np.median(implied))
    spread = max(1.4826 * float(np.median(np.abs(implied - mid))), 0.01)
    span = float(np.ptp(times[contact])) if contact.sum() > 1 else 0.0
    n_eff = max(1.0, span)  # about one independent sample per second (a gait cycle)
    data_var = spread**2 / n_eff
    lo, hi = np.log(config.stature_range)
    if not lo <= mid <= hi:
        return stature, stature_sd, True
    if "size" in config.cues:
        w = 1 / data_var + 1 / prior_sd**2
        mid = (mid / data_var + np.log(config.stature) / prior_sd**2) / w
        return float(np.exp(mid)), float(1 / np.sqrt(w)), dropped
    return float(np.exp(mid)), float(np.sqrt(data_var)), dropped
