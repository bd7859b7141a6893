"""One calibrated camera: depth from the floor, body size and time.

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

A temporal model that reads the floor (:class:`rmpl.TemporalLifter`, ``reads_floor``) takes
the place of the cues: the per-frame model finds and follows the people, and each track is
lifted again as a whole, its floor given (:func:`temporal_tracks`); its error radius is the
temporal model's.

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
from dataclasses import dataclass, replace

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.geometry.floor import ANKLE_HEIGHT, Floor, signed_distance
from rmpl.io.poses import JointSource, Poses3D
from rmpl.skeleton import BY_COUNT, COCO17

__all__ = [
    "CUES",
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
_HIPS = [_J["left_hip"], _J["right_hip"]]


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
    trunk = np.linalg.norm(shoulders - x[..., _HIPS, :].mean(-2), axis=-1)
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
    trunk = _angle_from(shoulders - x[..., _HIPS, :].mean(-2), up)
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


def _scaled(points: np.ndarray, center: np.ndarray, log_s: np.ndarray) -> np.ndarray:
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
        trunk = shoulders - x[:, _HIPS].mean(1)
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
    root = np.nanmean(points[:, _HIPS], axis=1) if T else np.zeros((0, 3))
    log_r = np.log(np.linalg.norm(root - center, axis=-1))  # the lifter's own root distance
    half = config.window / 2
    floor_depth = cues.floor + log_r
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
    prior_sd = config.stature_sd / config.stature  # log
    stature, stature_sd, dropped = config.stature, prior_sd, False
    if contact.sum() >= config.min_contact_frames:
        implied = cues.floor[contact] + np.log(cues.proxy[contact])  # log stature per frame
        implied = implied[np.isfinite(implied)]
        if len(implied) >= config.min_contact_frames:
            mid = float(np.median(implied))
            spread = max(1.4826 * float(np.median(np.abs(implied - mid))), 0.01)
            span = float(np.ptp(times[contact])) if contact.sum() > 1 else 0.0
            n_eff = max(1.0, span)  # about one independent sample per second (a gait cycle)
            data_var = spread**2 / n_eff
            lo, hi = np.log(config.stature_range)
            if not lo <= mid <= hi:
                dropped = True
                contact[:] = False
            elif "size" in config.cues:
                w = 1 / data_var + 1 / prior_sd**2
                mid = (mid / data_var + np.log(config.stature) / prior_sd**2) / w
                stature, stature_sd = float(np.exp(mid)), float(1 / np.sqrt(w))
            else:
                stature, stature_sd = float(np.exp(mid)), float(np.sqrt(data_var))
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


# --------------------------------------------------------------------------- the chain


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
    scaled = _scaled(pts, center, log_s)  # every joint moves with the depth
    split = np.cumsum([len(r) for r in rows])[:-1]
    if "time" not in config.cues:
        return _by_frame(np.split(scaled, split), np.split(sd, split), views, J, skeleton)
    index, ids = _track_index(np.split(scaled, split), cfg)
    P = index.shape[1]
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
        root = np.nanmean(pts[m][:, _HIPS], axis=1)
        log_r = np.log(np.linalg.norm(root - center, axis=-1))
        out[t_idx, p] = _scaled(pts[m], center, depth.log_depth - log_r)
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
    from rmpl.pipeline.runner import RunConfig, drop_far, smooth

    cfg = config or RunConfig()
    if is_temporal_checkpoint(cfg.model):
        return _single_view_temporal(
            keypoints, scores, rig, frames, fps, floor, cfg, temporal, joints
        )
    mono = monocular or MonocularConfig.for_model(cfg.model, floor_known=floor is not None)
    reads_floor = checkpoint_reads_floor(cfg.model)
    guess = 0.0  # log-depth error of a guessed floor, added to the uncertainty only
    if reads_floor and floor is not None and floor.source.startswith("calibration convention"):
        h = max(float(signed_distance(rig.centers[0], floor)), 0.2)
        guess = CONVENTION_FLOOR_SD / h
        log.warning(
            "the floor is the calibration's convention (%s), not measured: a floor off by e "
            "moves the person by about e x distance / %.2f m along the rays (give --floor, or "
            "a multi-view poses file of this rig)", floor.describe(), h,
        )  # fmt: skip
    if len(rig) != 1:
        raise ValueError(f"lift_single_view takes one camera, got {len(rig)}")
    T = keypoints.shape[0]
    keypoints, scores = drop_far(keypoints, scores, rig)
    present = (scores > 0).any(-1)[:, 0]  # (T, P)
    t_idx, p_idx = np.nonzero(present)
    kp = keypoints[t_idx, :, p_idx]  # (M, 1, J_2d, 2)
    sc = scores[t_idx, :, p_idx]
    res = monocular_people(kp, sc, t_idx, T, rig, fps, floor, mono, cfg, joints=joints)
    tracks = res.points
    interpolated = np.zeros(tracks.shape[:-1], bool)
    if temporal and len(tracks):
        tracks, interpolated = smooth(tracks, fps, cfg)
    ok = np.isfinite(tracks).all(-1)
    lifted = int(JointSource.LIFTED)
    flags = np.where(interpolated, int(JointSource.INTERPOLATED), np.where(ok, lifted, 0))
    tracks[~ok] = np.nan
    sigma = res.sigma.copy()
    if temporal and len(tracks):  # gap-filled frames: the neighbours' spread
        from rmpl.pipeline.filters import fill_gaps

        filled, _ = fill_gaps(sigma[..., None, None].repeat(3, -1), max_gap=cfg.max_gap)
        sigma = filled[..., 0, 0]
    sigma = np.hypot(sigma, guess)
    radius = RADIUS_50_1D * sigma[..., None] * np.linalg.norm(tracks - rig.centers[0], axis=-1)
    radius = np.where(ok, radius, np.nan)
    _log_summary(res, radius, floor, mono, reads_floor)
    return Poses3D(
        points=tracks,
        flags=flags.astype(np.uint8),
        num_views=np.where(ok, res.views, 0).astype(np.int32),
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
    from rmpl.pipeline.runner import drop_far

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
    keypoints, scores = drop_far(keypoints, scores, rig)
    present = (scores > 0).any(-1)[:, 0]  # (T, P)
    t_idx, p_idx = np.nonzero(present)
    kp, sc = keypoints[t_idx, :, p_idx], scores[t_idx, :, p_idx]  # (M, 1, J_2d, ...)
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
    where = floor.describe() if floor is not None else "no floor"
    how = "whole tracks lifted by the temporal model" if whole else "its per-frame model"
    log.info("one camera: %s %s, which reads the floor (%s) and learnt body sizes; depth "
             "comes from them, not from triangulation", how, cfg.model, where)  # fmt: skip
    r = radius[np.isfinite(radius)] * 1000 if radius is not None else np.zeros(0)
    if r.size:
        log.info("predicted error radius (50%%): median %.0f mm, 90th percentile %.0f mm "
                 "(per joint in poses.json/npz 'uncertainty')", np.median(r),
                 np.percentile(r, 90))  # fmt: skip
    return Poses3D(
        points=points,
        flags=flags.astype(np.uint8),
        num_views=(ok & detected).astype(np.int32) if views is None else views * ok,
        skeleton=res.skeleton,
        frames=np.arange(T) if frames is None else np.asarray(frames),
        fps=fps,
        person_ids=np.asarray(res.ids),
        uncertainty=radius,
    )


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
