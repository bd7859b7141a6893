"""Synthetic 2D-3D training pairs, generated as whole arrays (no per-sample Python).

A :class:`PairSource` turns a bank of real 3D poses into batches: each pose is mirrored,
scaled, turned and placed at random in a room, seen by a random camera setup (RCS), and
passed through a 2D detector model (:mod:`rmpl.synth.noise`). The batch holds the rays the
lifter sees, their confidences and the 3D targets. Rendered MHP shards
(:mod:`rmpl.synth.generate`) feed the same :class:`Batch` through :class:`ShardSource`, so the
trainer does not care where pairs come from.

Shape glossary: ``B`` batch, ``V`` views, ``J`` joints.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rmpl.geometry.camera import rodrigues
from rmpl.geometry.rays import rays_from_keypoints
from rmpl.skeleton import COCO17, HALPE26
from rmpl.synth.noise import (
    DEFAULT_INPUT_SETS,
    NoiseConfig,
    check_input_sets,
    detect_like,
    input_joint_sets,
)

__all__ = [
    "Batch",
    "PairSource",
    "SamplerConfig",
    "floor_rows",
    "place_poses",
    "perturb_extrinsics",
]


@dataclass
class Batch:
    """One batch of training pairs.

    Attributes:
        rays: (B, V, J, 6) float32, origin + unit direction, world metres (z up).
        scores: (B, V, J) float32, 0 = missing.
        target: (B, J, 3) float32, world metres.
        keypoints: (B, V, J, 2) pixels, NaN = missing (kept for baselines).
        K, R, t: (B, V, 3, 3), (B, V, 3, 3), (B, V, 3) the cameras used for the rays.
        floor: (B, 4) float32 floor planes ``[n_x, n_y, n_z, h]`` (``n . X = h``) given to
            a model that reads the floor, NaN rows = not given; None = no floor at all.
    """

    rays: np.ndarray
    scores: np.ndarray
    target: np.ndarray
    keypoints: np.ndarray
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    floor: np.ndarray | None = None


@dataclass(frozen=True)
class SamplerConfig:
    """How synthetic scenes are drawn.

    Attributes:
        camera_preset: random camera setup preset (see :mod:`rmpl.synth.cameras`).
        room: half-extent of the square floor area where people stand, metres.
        scale_range: uniform range of a body-size factor.
        mirror: probability of a left/right mirrored pose.
        drop_rate: random keypoint removal at training (thesis 6.11.2).
        calib_noise_deg: std of extrinsic rotation noise on the rays of training batches
            (0 = off; validation batches, ``train=False``, keep the true cameras).
        calib_noise_m: std of extrinsic translation noise on the rays, metres.
        noise_randomize: domain randomisation of the detector model on training batches.
            With strength s > 0 each batch draws its own detector: the 2D error and the
            confidence slope scaled by 2**U(-s, s), the outlier, swap, flip, missed-view,
            truncation and occluded-miss rates by 2**U(-2s, 2s) (capped at 0.5, or at the
            base rate when that is higher). An unseen
            detector is then one more draw rather than a new distribution. 0 = off.
        input_sets: with HALPE-26 poses, how often each kind of detector
            (:data:`rmpl.synth.noise.INPUT_SETS`: which of the nine points beyond COCO-17
            it gives) draws a sample, as (kind, weight) pairs (a table in TOML).
        keep_height: the poses stand on their own floor at z = 0 (a sequence bank,
            ``rmpl poses --sequences``: jumps, steps, sitting and lying as recorded) and keep
            their height; False stands each pose's lowest joint on z = 0.
        floor_rate: probability that a sample's batch carries its floor (``Batch.floor``,
            for models that read it); the rest say "unknown". Needs ``keep_height``.
        floor_noise_m: std of the error of a given floor's height, metres (an estimated or
            measured floor is not exact); validation batches get the exact floor.
        floor_tilt_deg: std of the error of a given floor's normal, degrees.
    """

    camera_preset: str = "universal"
    room: float = 2.0
    scale_range: tuple[float, float] = (0.88, 1.22)
    mirror: float = 0.5
    drop_rate: float = 0.2
    calib_noise_deg: float = 0.0
    calib_noise_m: float = 0.0
    noise_randomize: float = 0.0
    input_sets: tuple[tuple[str, float], ...] = DEFAULT_INPUT_SETS
    keep_height: bool = False
    floor_rate: float = 0.0
    floor_noise_m: float = 0.02
    floor_tilt_deg: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "input_sets", check_input_sets(self.input_sets))
        if not 0 <= self.noise_randomize <= 3:
            raise ValueError(f"noise_randomize must be in [0, 3], got {self.noise_randomize}")
        if not 0 <= self.floor_rate <= 1:
            raise ValueError(f"floor_rate must be in [0, 1], got {self.floor_rate}")
        if self.floor_rate > 0 and not self.keep_height:
            raise ValueError("floor_rate > 0 needs keep_height = true (poses on a known floor)")
        if self.floor_noise_m < 0 or self.floor_tilt_deg < 0:
            raise ValueError("floor_noise_m and floor_tilt_deg must be >= 0")


def floor_rows(
    size: int, rate: float, noise_m: float, tilt_deg: float, rng: np.random.Generator
) -> np.ndarray | None:
    """``Batch.floor`` for scenes whose floor is z = 0: (size, 4) rows ``[n, h]``, given with
    probability ``rate`` (else NaN) and perturbed by ``noise_m`` / ``tilt_deg``; None when
    ``rate`` is 0 (a model that reads the floor then sees "unknown")."""
    if rate <= 0:
        return None
    tilt = rng.standard_normal((size, 2)) * np.deg2rad(tilt_deg)
    n = np.concatenate([tilt, np.ones((size, 1))], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rows = np.concatenate([n, noise_m * rng.standard_normal((size, 1))], -1)
    rows[rng.random(size) >= rate] = np.nan
    return rows.astype(np.float32)


_RATES = (
    "outlier_rate",
    "swap_rate",
    "flip_rate",
    "miss_view_rate",
    "truncate_rate",
    "occluded_drop",
)


def randomized_noise(noise: NoiseConfig, strength: float, rng: np.random.Generator) -> NoiseConfig:
    """One random detector around ``noise`` (see ``SamplerConfig.noise_randomize``)."""
    if strength <= 0:
        return noise
    scale = 2.0 ** rng.uniform(-strength, strength)
    rates = 2.0 ** rng.uniform(-2 * strength, 2 * strength, len(_RATES))
    return replace(
        noise,
        joint_sigma=tuple(scale * np.asarray(noise.joint_sigma)),
        conf_slope=noise.conf_slope * 2.0 ** rng.uniform(-strength, strength),
        **{
            k: min(max(0.5, getattr(noise, k)), getattr(noise, k) * f)
            for k, f in zip(_RATES, rates, strict=True)
        },
    )


def place_poses(poses: np.ndarray, rng: np.random.Generator, cfg: SamplerConfig) -> np.ndarray:
    """Mirror, scale, turn about z and place poses on the floor of a room (the lowest
    joint on z = 0, or with ``cfg.keep_height`` the poses' own floor z = 0).

    Args:
        poses: (B, J, 3) COCO-17 or HALPE-26 joints, metres, z up.

    Returns:
        (B, J, 3) placed poses.
    """
    B = poses.shape[0]
    mirror = rng.random(B) < cfg.mirror
    skel = HALPE26 if poses.shape[1] == HALPE26.num_joints else COCO17
    flipped = poses[:, skel.flip_permutation()] * np.array([-1.0, 1.0, 1.0])
    poses = np.where(mirror[:, None, None], flipped, poses)
    root = poses[:, 11:13].mean(1)  # mid-hip
    floor = np.zeros(B) if cfg.keep_height else np.nanmin(poses[..., 2], axis=1)
    origin = np.stack([root[:, 0], root[:, 1], floor], -1)[:, None]
    scale = rng.uniform(*cfg.scale_range, (B, 1, 1))
    yaw = rng.uniform(-np.pi, np.pi, B)
    Rz = rodrigues(np.stack([np.zeros(B), np.zeros(B), yaw], -1))
    local = np.einsum("bij,bnj->bni", Rz, (poses - origin) * scale)
    place = np.concatenate([rng.uniform(-cfg.room, cfg.room, (B, 2)), np.zeros((B, 1))], -1)
    return local + place[:, None]


def perturb_extrinsics(
    R: np.ndarray, t: np.ndarray, deg: float, metres: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Calibration error: rotate each camera by ~N(0, deg) and move its centre by ~N(0, m).

    Args:
        R: (*, 3, 3). t: (*, 3).

    Returns:
        Perturbed (R, t), same shapes.
    """
    lead = R.shape[:-2]
    axis = rng.standard_normal((*lead, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.deg2rad(deg) * rng.standard_normal((*lead, 1))
    dR = rodrigues(axis * angle)
    C = -np.einsum("...ji,...j->...i", R, t) + metres * rng.standard_normal((*lead, 3))
    R2 = dR @ R
    return R2, -np.einsum("...ij,...j->...i", R2, C)


class PairSource:
    """Fresh synthetic pairs from a pose bank, as whole arrays.

    Args:
        poses: (N, J, 3) COCO-17 poses, metres, z up.
        sampler: scene sampling parameters.
        noise: detector noise model.
        seed: random seed (a fixed seed gives a fixed validation set).
    """

    def __init__(
        self,
        poses: np.ndarray,
        sampler: SamplerConfig | None = None,
        noise: NoiseConfig | None = None,
        seed: int | None = None,
    ) -> None:
        self.poses = np.asarray(poses, dtype=np.float64)
        if self.poses.ndim != 3 or self.poses.shape[1:] not in ((17, 3), (26, 3)):
            raise ValueError(f"poses must have shape (N, 17 or 26, 3), got {self.poses.shape}")
        self.sampler = sampler or SamplerConfig()
        self.noise = noise or NoiseConfig()
        self.rng = np.random.default_rng(seed)

    def batch(self, size: int, num_views: int, train: bool = True) -> Batch:
        """Draw ``size`` scenes seen by ``num_views`` cameras."""
        from rmpl.synth.cameras import sample_cameras

        rng, cfg = self.rng, self.sampler
        idx = rng.integers(0, len(self.poses), size)
        joints = place_poses(self.poses[idx], rng, cfg)
        center = joints[:, 11:13].mean(1)
        K, R, t, wh = sample_cameras(num_views, center, cfg.camera_preset, rng)
        noise = self.noise
        if train and cfg.noise_randomize > 0:
            noise = randomized_noise(noise, cfg.noise_randomize, rng)
        kp, scores = detect_like(joints, K, R, t, wh, rng, noise)
        if joints.shape[1] == HALPE26.num_joints:  # the detector's joint set
            given = input_joint_sets(size, dict(cfg.input_sets), rng)[:, None]  # (B, 1, J)
            scores = np.where(given, scores, 0.0)
            kp = np.where(given[..., None], kp, np.nan)
        if train and cfg.drop_rate > 0:
            drop = rng.random(scores.shape) < cfg.drop_rate
            scores = np.where(drop, 0.0, scores)
            kp = np.where(drop[..., None], np.nan, kp)
        Rr, tr = R, t
        if train and (cfg.calib_noise_deg > 0 or cfg.calib_noise_m > 0):
            Rr, tr = perturb_extrinsics(R, t, cfg.calib_noise_deg, cfg.calib_noise_m, rng)
        rays = rays_from_keypoints(kp, K=K, R=Rr, t=tr)
        rays = np.where(scores[..., None] > 0, rays, 0.0)
        noisy = (cfg.floor_noise_m, cfg.floor_tilt_deg) if train else (0.0, 0.0)
        return Batch(
            rays.astype(np.float32),
            scores.astype(np.float32),
            joints.astype(np.float32),
            kp,
            K,
            Rr,
            tr,
            floor_rows(size, cfg.floor_rate, *noisy, rng),
        )
