"""Single-body frames: posed, rendered, occluded, detected, written as one shard.

Part of :mod:`rmpl.synth.generate` (``rmpl generate``).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.synth.generate.detectors import detect_person, follows, in_joint_set
from rmpl.synth.shards import (
    SHARD_ARRAYS,
    shard_path,
    write_shard,
)

log = logging.getLogger(__name__)


def _scale_cameras(K: np.ndarray, size: np.ndarray, target: tuple[int, int]):
    """Fit each camera's image into ``target`` (w, h): scale, then centre. Pixel centres
    at integers: u' = s (u + 0.5) - 0.5 + offset."""
    w, h = target
    s = np.minimum(w / size[..., 0], h / size[..., 1])  # (*, V)
    K = K.copy()
    K[..., 0, 0] *= s
    K[..., 1, 1] *= s
    K[..., 0, 2] = s * (K[..., 0, 2] + 0.5) - 0.5 + (w - s * size[..., 0]) / 2
    K[..., 1, 2] = s * (K[..., 1, 2] + 0.5) - 0.5 + (h - s * size[..., 1]) / 2
    return K, np.broadcast_to(np.array([w, h]), size.shape).copy()


def occlude(
    images: list[np.ndarray],
    points: np.ndarray,
    rate: float,
    side: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Paste black squares over keypoints (thesis 6.11.1), in place.

    Args:
        images: n RGB images (H, W, 3) uint8, modified in place.
        points: the true keypoints per image, shape (n, J, 2), pixels.
        rate: probability per keypoint. side: square side, pixels.

    Returns:
        Which keypoints got a square, shape (n, J) bool.
    """
    hit = rng.random(points.shape[:2]) < rate
    half = side / 2
    for i, im in enumerate(images):
        h, w = im.shape[:2]
        for j in np.flatnonzero(hit[i]):
            u, v = points[i, j]
            if not (np.isfinite(u) and np.isfinite(v)):
                continue
            x0, y0 = int(round(u - half)), int(round(v - half))
            im[max(y0, 0) : max(min(y0 + side, h), 0), max(x0, 0) : max(min(x0 + side, w), 0)] = 0
    return hit


def _draw_poses(worker, n: int, first: int, rng: np.random.Generator):
    """n plausible posed bodies; returns (bodies, meta dict, rejected count)."""
    from rmpl.synth.body import sample_phenotypes
    from rmpl.synth.retarget import implausible, mirror_pose, perturb_pose, retarget

    cfg, body, bank = worker.cfg, worker.body, worker.bank
    if bank is not None:
        order = np.random.default_rng([cfg.seed, 2**31 - 1]).permutation(len(bank))
        queue = list(order[(first + np.arange(n)) % len(bank)])
    verts, kps, meta, rejected, tries = [], [], [], 0, 0
    while len(verts) < n:
        b = min(cfg.batch_size, n - len(verts))
        tries += b
        if tries > n * cfg.max_tries:
            raise RuntimeError(
                f"{rejected} of {tries - b} poses were implausible; check 'poses' ({cfg.poses})"
            )
        phen = sample_phenotypes(b, rng, cfg.min_age)
        mirrored = rng.random(b) < cfg.mirror
        if bank is None:
            pose = body.sample_poses(b, rng)[..., :3, :3]
            idx = np.full(b, -1)
        else:
            idx = np.array([queue.pop(0) if queue else rng.integers(len(bank)) for _ in range(b)])
            pose = retarget(body, bank, idx, phen)
            pose = perturb_pose(pose, body.bone_names, rng, cfg.perturb_deg)
        pose = np.where(mirrored[:, None, None, None], mirror_pose(pose, body.bone_names), pose)
        bodies = body(pose, phen)
        bad = implausible(bodies.keypoints)
        rejected += int(bad.sum())
        for i in np.flatnonzero(~bad):
            verts.append(bodies.vertices[i])
            kps.append(bodies.keypoints[i])
            k = int(idx[i])
            meta.append(
                (
                    phen[i],
                    "random" if k < 0 else str(bank.subject[k]),
                    "" if k < 0 else str(bank.clip[k]),
                    -1 if k < 0 else int(bank.frame[k]),
                    bool(mirrored[i]),
                )
            )
    return np.stack(verts), np.stack(kps), meta, rejected


def frame_shard(worker, index: int, first: int, n: int, out: str | Path) -> dict:
    """Single-body frames ``first .. first + n - 1`` as shard ``index``
    (:func:`rmpl.synth.generate.worker.generate_shard`)."""
    cfg = worker.cfg
    rng = np.random.default_rng([cfg.seed, index])
    # The squares draw from their own stream: a set made with occlusion_rate > 0 has the
    # same meshes, cameras and images as the one made without (a paired experiment).
    occ_rng = np.random.default_rng([cfg.seed, index, 1])
    times = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    parts: dict[str, list] = {k: [] for k in SHARD_ARRAYS}
    rejected = 0
    for start in range(0, n, cfg.batch_size):
        b = min(cfg.batch_size, n - start)
        t0 = time.perf_counter()
        posed = _pose_batch(worker, b, first + start, rng)
        t1 = time.perf_counter()
        images, occ = _render_batch(worker, posed, rng, occ_rng)
        t2 = time.perf_counter()
        kp2d, scores = _detect_apart(worker.detector, images)
        kp2d, scores = in_joint_set(worker.detector, kp2d, scores, cfg.joints)
        t3 = time.perf_counter()
        times["pose"] += t1 - t0
        times["render"] += t2 - t1
        times["detect"] += t3 - t2
        rejected += posed.rejected
        for key, array in _batch_arrays(posed, kp2d, scores, occ).items():
            parts[key].append(array)
    arrays = {k: np.concatenate(v) for k, v in parts.items()}
    stats = {
        "shard": index,
        "meshes": n,
        "views": n * cfg.views,
        "rejected": rejected,
        "missed_joints": int((arrays["scores"] == 0).sum()),
        "missed_views": int((arrays["scores"] == 0).all(-1).sum()),
        "seconds": times,
    }
    write_shard(shard_path(out, index), arrays, stats)
    return stats


def _detect_apart(detector, images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Detect images of unrelated scenes: a detector that follows people starts afresh on
    each image."""
    if not follows(detector):
        return detect_person(detector, images)
    parts = []
    for im in images:
        detector.reset()
        parts.append(detect_person(detector, [im]))
    return np.concatenate([k for k, _ in parts]), np.concatenate([s for _, s in parts])


@dataclass
class _Posed:
    """One batch of b posed bodies placed in the room, with their V cameras."""

    vertices: np.ndarray  # (b, N, 3) world metres
    joints: np.ndarray  # (b, 17, 3) COCO-17, world metres
    meta: list[tuple]  # per body: phenotypes, subject, clip, frame, mirrored
    rejected: int  # implausible poses drawn and replaced
    K: np.ndarray  # (b, V, 3, 3) pixels
    R: np.ndarray  # (b, V, 3, 3)
    t: np.ndarray  # (b, V, 3) metres
    size: np.ndarray  # (b, V, 2) pixels
    projected: np.ndarray  # (b, V, 17, 2) joints projected, pixels
    colors: np.ndarray  # (b, N, 3) vertex RGB of the outfits


def _pose_batch(worker, b: int, first: int, rng: np.random.Generator) -> _Posed:
    """b plausible bodies (mesh ``first`` onwards) placed in the room, seen by random cameras."""
    from rmpl.geometry.camera import project
    from rmpl.synth.body import place_bodies
    from rmpl.synth.cameras import sample_cameras
    from rmpl.synth.render import random_outfits

    cfg = worker.cfg
    verts, kps, meta, rejected = _draw_poses(worker, b, first, rng)
    yaw = rng.uniform(-np.pi, np.pi, b)
    where = rng.uniform(-cfg.room, cfg.room, (b, 2))
    verts, kps = place_bodies(verts, kps, yaw, where)
    center = kps[:, 11:13].mean(axis=1).astype(float)
    K, R, t, size = sample_cameras(cfg.views, center, cfg.camera_preset, rng)
    if cfg.image_size:
        K, size = _scale_cameras(K, size, tuple(cfg.image_size))
    proj = project(kps[:, None].astype(float), K[:, :, None], R[:, :, None], t[:, :, None])
    colors = random_outfits(worker.body.vertex_parts, b, rng)
    return _Posed(verts, kps, meta, rejected, K, R, t, size, proj, colors)


def _render_batch(worker, posed: _Posed, rng, occ_rng) -> tuple[list, np.ndarray]:
    """The b * V images (body-major), and the joints under a pasted square (b * V, 17)."""
    cfg = worker.cfg
    p, bv, J = posed, len(posed.joints) * cfg.views, posed.joints.shape[1]
    images = worker.renderer.render(p.vertices, p.colors, p.K, p.R, p.t, p.size, rng=rng)
    occ = np.zeros((bv, J), bool)
    if cfg.occlusion_rate > 0:
        occ = occlude(
            images, p.projected.reshape(bv, J, 2), cfg.occlusion_rate, cfg.occlusion_size, occ_rng
        )
    return images, occ


def _batch_arrays(posed: _Posed, kp2d, scores, occ: np.ndarray) -> dict[str, np.ndarray]:
    """One batch's part of every :data:`SHARD_ARRAYS` array, in their dtypes."""
    b, V = posed.K.shape[:2]
    J = posed.joints.shape[1]
    phen, subject, clip, frame, mirrored = zip(*posed.meta, strict=True)
    return {
        "joints3d": posed.joints.astype(np.float32),
        "keypoints": np.asarray(kp2d, np.float32).reshape(b, V, J, 2),
        "scores": np.asarray(scores, np.float32).reshape(b, V, J),
        "projected": posed.projected.astype(np.float32),
        "K": posed.K,
        "R": posed.R,
        "t": posed.t,
        "size": posed.size.astype(np.int32),
        "occluded": occ.reshape(b, V, J),
        "phenotypes": np.asarray(phen, np.float32),
        "subject": np.asarray(subject, str),
        "clip": np.asarray(clip, str),
        "frame": np.asarray(frame, np.int64),
        "mirrored": np.asarray(mirrored, bool),
    }
