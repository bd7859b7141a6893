"""A parametric model of 2D detector error, for fast synthetic training pairs.

Given 3D COCO-17 joints and cameras, :func:`detect_like` returns what a 2D detector would
plausibly output: keypoints with per-joint noise that scales with the person's size in
pixels, confidences that fall as the error grows, self-occlusion (noisier, less confident,
sometimes missed), left/right swaps, outliers, people cut off by the image border or
missing from a view, and keypoints outside the image dropped.

All parameters live in :class:`NoiseConfig` so that they can be fitted to the statistics
of a real detector on renders (``rmpl generate --stats``).

Shape glossary: ``B`` samples, ``V`` views, ``J`` joints.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np

from rmpl.geometry.camera import project
from rmpl.skeleton import COCO17, HALPE26

__all__ = [
    "NoiseConfig",
    "INPUT_SETS",
    "detect_like",
    "occlusion_mask",
    "joint_sigmas",
    "input_joint_sets",
    "check_input_sets",
    "DEFAULT_INPUT_SETS",
]

# Relative 2D error per COCO-17 joint (fraction of the person's pixel height): face points
# are precise, wrists, elbows and hips the hardest. Set so that the mean error matches
# MediaPipe BlazePose on MHP renders (docs/mhp.md: elbows and wrists 16-18 px, median
# 6.9 px over all joints, for a 479 px tall person).
_JOINT_SIGMA = np.array(
    [
        0.008,
        0.008,
        0.008,
        0.010,
        0.010,
        0.013,
        0.013,
        0.018,
        0.018,
        0.022,
        0.022,
        0.020,
        0.020,
        0.015,
        0.015,
        0.016,
        0.016,
    ]
)

# The same for HALPE-26's other nine points (head top, neck, mid-hip, big toes, small toes,
# heels), used when ``joint_sigma`` has only COCO-17's: the head top and neck like the
# shoulders and ears, the mid-hip like the hips, the feet like the ankles and a little worse.
_EXTRA_SIGMA = np.array([0.013, 0.013, 0.020, 0.018, 0.018, 0.018, 0.018, 0.018, 0.018])


def joint_sigmas(joint_sigma, num_joints: int) -> np.ndarray:
    """Per-joint 2D error (J,) for ``num_joints`` joints: ``joint_sigma`` as given, or
    COCO-17's followed by HALPE-26's defaults (:data:`_EXTRA_SIGMA`)."""
    sigma = np.asarray(joint_sigma, float)
    if len(sigma) == num_joints:
        return sigma
    if len(sigma) == COCO17.num_joints and num_joints == HALPE26.num_joints:
        return np.concatenate([sigma, _EXTRA_SIGMA])
    raise ValueError(f"joint_sigma has {len(sigma)} values for {num_joints} joints")


def _flip_pairs(num_joints: int) -> np.ndarray:
    return np.array(HALPE26.flip_pairs if num_joints == HALPE26.num_joints else COCO17.flip_pairs)


@dataclass(frozen=True)
class NoiseConfig:
    """Parameters of :func:`detect_like` (fractions are of the person's pixel height).

    Attributes:
        joint_sigma: per-joint standard deviation of the 2D error, shape (J,) (COCO-17's
            serve HALPE-26 too, see :func:`joint_sigmas`).
        sigma_spread: log-normal spread of a per-view quality factor on the error.
        occluded_sigma: error multiplier for self-occluded joints.
        occluded_drop: probability that an occluded joint is missed.
        conf_visible: mean confidence of a clean visible joint.
        conf_occluded: mean confidence of an occluded joint.
        conf_slope: confidence lost per unit of error / (0.05 * height).
        conf_jitter: standard deviation of random confidence noise.
        conf_gamma: range of a per-sample power applied to confidences (detectors differ
            in how they scale confidence; the lifter should rely on the ranking).
        outlier_rate: probability that a keypoint lands on another joint or nearby.
        swap_rate: probability per view and left/right pair of a swap.
        flip_rate: probability per view that the whole body is mirrored (front/back).
        miss_view_rate: probability that a person is not detected at all in a view.
        truncate_rate: probability that a view cuts the person at a random line.
        limb_radius: radius of the limb capsules for self-occlusion, metres.
        torso_radius: radius of the torso capsules, metres.
    """

    joint_sigma: tuple[float, ...] = tuple(_JOINT_SIGMA)
    sigma_spread: float = 0.35
    occluded_sigma: float = 2.5
    occluded_drop: float = 0.25
    conf_visible: float = 0.85
    conf_occluded: float = 0.45
    conf_slope: float = 0.25
    conf_jitter: float = 0.08
    conf_gamma: tuple[float, float] = (0.6, 1.6)
    outlier_rate: float = 0.02
    swap_rate: float = 0.02
    flip_rate: float = 0.01
    miss_view_rate: float = 0.04
    truncate_rate: float = 0.08
    limb_radius: float = 0.06
    torso_radius: float = 0.11
    extra: dict = field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: dict) -> NoiseConfig:
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown noise keys {sorted(unknown)}; known: {sorted(known)}")
        d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        return cls(**d)

    def to_dict(self) -> dict:
        return asdict(self)


_LIMBS = [(5, 7), (7, 9), (6, 8), (8, 10), (11, 13), (13, 15), (12, 14), (14, 16)]
_TORSO = [(5, 12), (6, 11), (5, 11), (6, 12), (5, 6), (11, 12)]


def occlusion_mask(
    joints: np.ndarray, centers: np.ndarray, limb_radius: float, torso_radius: float
) -> np.ndarray:
    """Which joints are hidden behind the body's own limbs or torso.

    A joint is occluded in a view when the segment from the camera to the joint passes
    within a capsule's radius of a limb or torso segment (not touching the joint), at a
    point nearer the camera.

    Args:
        joints: (B, J, 3) COCO-17 joints, metres. centers: (B, V, 3) camera centres.

    Returns:
        (B, V, J) bool.
    """
    segs = _LIMBS + _TORSO
    radius = np.array([limb_radius] * len(_LIMBS) + [torso_radius] * len(_TORSO))
    a = joints[:, [s[0] for s in segs]]  # (B, S, 3)
    b = joints[:, [s[1] for s in segs]]
    C = centers[:, :, None, None, :]  # (B, V, 1, 1, 3)
    X = joints[:, None, :, None, :]  # (B, 1, J, 1, 3)
    A, Bp = a[:, None, None], b[:, None, None]  # (B, 1, 1, S, 3)
    # Closest points between segment C->X (param s) and segment A->B (param u).
    d1, d2, r = X - C, Bp - A, C - A
    a11 = (d1 * d1).sum(-1)
    a22 = (d2 * d2).sum(-1)
    a12 = (d1 * d2).sum(-1)
    b1 = (d1 * r).sum(-1)
    b2 = (d2 * r).sum(-1)
    den = a11 * a22 - a12**2
    s = np.clip(np.where(den > 1e-9, (a12 * b2 - a22 * b1) / np.maximum(den, 1e-9), 0.0), 0, 1)
    u = np.clip((a12 * s + b2) / np.maximum(a22, 1e-9), 0, 1)
    s = np.clip((a12 * u - b1) / np.maximum(a11, 1e-9), 0, 1)
    dist = np.linalg.norm(C + s[..., None] * d1 - (A + u[..., None] * d2), axis=-1)
    seg_len = np.sqrt(a11)  # camera-to-joint distance
    in_front = s * seg_len < seg_len - radius  # the blocking point is nearer than the joint
    J = joints.shape[1]
    own = np.zeros((J, len(segs)), bool)  # a joint is not hidden by its own segments
    for k, (i, j) in enumerate(segs):
        own[i, k] = own[j, k] = True
    hit = (dist < radius) & in_front & ~own[None, None]
    return hit.any(-1)


def detect_like(
    joints: np.ndarray,
    K: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    size: np.ndarray,
    rng: np.random.Generator,
    config: NoiseConfig | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Simulate a 2D detector on a person seen by several cameras.

    Args:
        joints: (B, J, 3) COCO-17 or HALPE-26 joints, world metres.
        K: (B, V, 3, 3). R: (B, V, 3, 3). t: (B, V, 3). size: (B, V, 2) image (w, h).
        rng: random generator.
        config: noise parameters.

    Returns:
        keypoints (B, V, J, 2) pixels (NaN where missed) and scores (B, V, J) in [0, 1]
        (0 where missed).
    """
    cfg = config or NoiseConfig()
    shape = (*K.shape[:2], joints.shape[1])  # (B, V, J): the shape of the random draws
    uv = project(joints[:, None], K[:, :, None], R[:, :, None], t[:, :, None])  # (B,V,J,2)
    lo, hi = np.nanmin(uv, axis=2), np.nanmax(uv, axis=2)  # (B, V, 2)
    height = np.nan_to_num(np.max(hi - lo, axis=-1), nan=1.0).clip(5, None)  # (B, V)
    centers = -np.einsum("bvji,bvj->bvi", R, t)
    occ = occlusion_mask(joints, centers, cfg.limb_radius, cfg.torso_radius)

    kp, out = _noisy_keypoints(uv, height, occ, shape, cfg, rng)
    conf = _confidences(kp, uv, height, occ, out, shape, cfg, rng)
    kp, conf = _swap_sides(kp, conf, shape, cfg, rng)
    # Missed: occluded drops, whole-person misses, truncation, outside the image.
    missed = occ & (rng.random(occ.shape) < cfg.occluded_drop)
    missed |= rng.random((*shape[:2], 1)) < cfg.miss_view_rate
    missed |= _truncated(uv, lo, hi, shape, cfg, rng)
    missed |= ~_inside(kp, size) | ~_inside(uv, size) | ~np.isfinite(kp).all(-1)
    kp[missed] = np.nan
    conf[missed] = 0.0
    return kp, conf


def _noisy_keypoints(uv, height, occ, shape, cfg: NoiseConfig, rng: np.random.Generator):
    """Projections ``uv`` (B, V, J, 2) plus an error that grows with the person's pixel
    ``height`` (B, V), a per-view quality and occlusion ``occ`` (B, V, J); some land on
    another joint (limb confusion). ``shape`` is (B, V, J), that of the random draws.

    Returns:
        keypoints (B, V, J, 2) pixels, and which are such outliers (B, V, J) bool.
    """
    Bn, V, J = shape
    quality = np.exp(cfg.sigma_spread * rng.standard_normal((Bn, V, 1)))
    sigma = joint_sigmas(cfg.joint_sigma, J)[None, None] * height[..., None] * quality
    sigma = np.where(occ, sigma * cfg.occluded_sigma, sigma)
    err = sigma[..., None] * rng.standard_normal((Bn, V, J, 2))
    kp = uv + err
    out = rng.random((Bn, V, J)) < cfg.outlier_rate
    other = rng.integers(0, J, (Bn, V, J))
    kp_other = np.take_along_axis(uv, other[..., None].repeat(2, -1), axis=2)
    return np.where(out[..., None], kp_other + err, kp), out


def _confidences(kp, uv, height, occ, out, shape, cfg: NoiseConfig, rng: np.random.Generator):
    """Scores (B, V, J): lower when occluded and as the error ``kp - uv`` grows, jittered,
    random for the outliers ``out``, then raised to a per-sample power."""
    err_px = np.linalg.norm(kp - uv, axis=-1)
    base = np.where(occ, cfg.conf_occluded, cfg.conf_visible)
    conf = base - cfg.conf_slope * err_px / (0.05 * height[..., None])
    conf = conf + cfg.conf_jitter * rng.standard_normal(conf.shape)
    conf = np.where(out, rng.uniform(0.1, 0.7, conf.shape), conf)
    conf = np.clip(conf, 0.02, 1.0)
    gamma = rng.uniform(*cfg.conf_gamma, (shape[0], 1, 1))
    return conf**gamma


def _swap_sides(kp, conf, shape, cfg: NoiseConfig, rng: np.random.Generator):
    """Left/right swaps of single pairs, and whole-body mirror confusions, per view."""
    Bn, V, J = shape
    pairs = _flip_pairs(J)
    swap = rng.random((Bn, V, len(pairs))) < cfg.swap_rate
    swap |= rng.random((Bn, V, 1)) < cfg.flip_rate
    perm = np.broadcast_to(np.arange(J), (Bn, V, J)).copy()
    for k, (l, r) in enumerate(pairs):
        perm[..., l] = np.where(swap[..., k], r, perm[..., l])
        perm[..., r] = np.where(swap[..., k], l, perm[..., r])
    kp = np.take_along_axis(kp, perm[..., None].repeat(2, -1), axis=2)
    return kp, np.take_along_axis(conf, perm, axis=2)


def _truncated(uv, lo, hi, shape, cfg: NoiseConfig, rng: np.random.Generator) -> np.ndarray:
    """Joints (B, V, J) beyond a random horizontal or vertical line across the person's
    box ``lo``-``hi`` (B, V, 2), in the views that cut the person."""
    Bn, V = shape[:2]
    trunc = rng.random((Bn, V)) < cfg.truncate_rate
    axis = rng.integers(0, 2, (Bn, V))
    side = rng.random((Bn, V)) < 0.5
    frac = rng.uniform(0.2, 0.8, (Bn, V))
    cut = np.where(
        axis == 0,
        lo[..., 0] + frac * (hi[..., 0] - lo[..., 0]),
        lo[..., 1] + frac * (hi[..., 1] - lo[..., 1]),
    )
    coord = np.where(axis[..., None] == 0, uv[..., 0], uv[..., 1])  # (B, V, J)
    beyond = np.where(side[..., None], coord > cut[..., None], coord < cut[..., None])
    return trunc[..., None] & beyond


def _inside(points: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Which pixel ``points`` (B, V, J, 2) lie in their image of ``size`` (B, V, 2)."""
    w, h = size[..., 0:1], size[..., 1:2]
    u, v = points[..., 0], points[..., 1]
    return (u >= 0) & (u <= w - 1) & (v >= 0) & (v <= h - 1)


#: Which of HALPE-26's nine extra points a detector gives, by kind of detector: COCO-17
#: ones none, BlazePose the heels and (as the big toe) the foot index, OpenPose BODY_25 all
#: but the head top, HALPE-26 all. (BODY_25B, head top and feet, is not a kind of its own.)
INPUT_SETS: dict[str, tuple[str, ...]] = {
    "coco17": (),
    "blazepose": ("left_big_toe", "right_big_toe", "left_heel", "right_heel"),
    "body25": HALPE26.joints[18:],
    "halpe26": HALPE26.joints[17:],
}


#: The default mix of detector kinds in training (kind, weight).
DEFAULT_INPUT_SETS: tuple[tuple[str, float], ...] = (
    ("coco17", 0.4),
    ("blazepose", 0.2),
    ("body25", 0.2),
    ("halpe26", 0.2),
)


def check_input_sets(pairs) -> tuple[tuple[str, float], ...]:
    """``(kind, weight)`` pairs (or a kind -> weight table) checked: known kinds, weights
    >= 0 with a positive sum. Raises ValueError naming the problem."""
    pairs = tuple(pairs.items()) if isinstance(pairs, dict) else tuple(map(tuple, pairs))
    unknown = sorted({k for k, _ in pairs} - set(INPUT_SETS))
    weights = [w for _, w in pairs]
    if unknown or any(not w >= 0 for w in weights) or not sum(weights) > 0:
        raise ValueError(
            f"input_sets must weigh kinds of {sorted(INPUT_SETS)} with weights >= 0 and a "
            f"positive sum, got {pairs}"
        )
    return pairs


def input_joint_sets(
    batch: int, probabilities: dict[str, float], rng: np.random.Generator
) -> np.ndarray:
    """Which HALPE-26 joints each sample's detector gives, (batch, 26) bool: one kind of
    :data:`INPUT_SETS` per sample (every view of a rig runs the same detector), drawn with
    ``probabilities`` (kind -> weight)."""
    kinds = list(probabilities)
    w = np.array([probabilities[k] for k in kinds], float)
    draw = rng.choice(len(kinds), size=batch, p=w / w.sum())
    table = np.zeros((len(kinds), HALPE26.num_joints), bool)
    for i, k in enumerate(kinds):
        table[i, :17] = True
        table[i, HALPE26.indices(INPUT_SETS[k])] = True
    return table[draw]
