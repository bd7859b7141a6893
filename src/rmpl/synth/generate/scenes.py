"""Multi-person scenes: several bodies a gap apart in one room, their detections matched
to the bodies.

Part of :mod:`rmpl.synth.generate` (``rmpl generate``).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from rmpl.synth.generate.detectors import follows, in_joint_set
from rmpl.synth.generate.frames import _draw_poses, _scale_cameras
from rmpl.synth.shards import (
    SCENE_ARRAYS,
    shard_path,
    write_shard,
)

log = logging.getLogger(__name__)

#: A detection slot is of a body when its keypoints lie within this fraction of the body's
#: projected size of the body's projected joints (median over the detected joints).
MATCH_TOLERANCE = 0.2
#: Least distance between two bodies of a scene, metres.
SCENE_GAP = 0.6


def room_fits(n: int, room: float, gap: float = SCENE_GAP) -> bool:
    """Whether +-``room`` metres leaves ``n`` random positions ``gap`` apart easily: a square
    grid of them at twice the gap fits (random draws then succeed within a few tries).

    >>> room_fits(4, 1.0), room_fits(8, 0.5)
    (True, False)
    """
    side = int(np.ceil(np.sqrt(n)))
    return 2 * room >= 2 * gap * (side - 1)


def spread(n: int, room: float, rng: np.random.Generator, gap: float = SCENE_GAP) -> np.ndarray:
    """n floor positions uniform within +-``room`` metres, at least ``gap`` metres apart
    (redrawn up to 100 times; then the last draw is kept, with a warning). Returns (n, 2)
    metres."""
    for _ in range(100):
        where = rng.uniform(-room, room, (n, 2))
        d = np.linalg.norm(where[:, None] - where[None], axis=-1) + np.eye(n) * 1e9
        if d.min() >= gap:
            return where
    log.warning("%d bodies %g m apart did not fit in +-%g m: two may overlap", n, gap, room)
    return where


def match_detections(
    keypoints: np.ndarray, scores: np.ndarray, projected: np.ndarray, present: np.ndarray
) -> np.ndarray:
    """Which body each detection slot of one image is of, by the projected joints.

    The cost of (slot, body) is the median pixel distance over the slot's detected joints,
    divided by the body's projected size (the larger side of its joints' box); slots and
    bodies are paired by the Hungarian method, and a pair counts when its cost is below
    :data:`MATCH_TOLERANCE`.

    Args:
        keypoints: (N, J, 2) pixels; scores: (N, J), 0 = missing.
        projected: (P, J, 2) pixels; present: (P,) bool.

    Returns:
        (N,) int8: the body index, -1 for none.
    """
    import warnings

    from scipy.optimize import linear_sum_assignment

    size = np.ptp(projected, axis=1).max(-1).clip(1.0, None)  # (P,)
    dist = np.linalg.norm(keypoints[:, None] - projected[None], axis=-1)  # (N, P, J)
    dist = np.where((scores > 0)[:, None], dist, np.nan)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # empty slots, absent bodies
        cost = np.nanmedian(dist, axis=-1) / size  # (N, P)
    cost = np.where(present[None] & np.isfinite(cost), cost, 1e6)
    out = np.full(len(keypoints), -1, np.int8)
    for n, p in zip(*linear_sum_assignment(cost), strict=True):
        if cost[n, p] < MATCH_TOLERANCE:
            out[n] = p
    return out


def _hidden(ids: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Joints (P, J) whose pixel shows another body. ids: (H, W) body per pixel, -1 none;
    uv: (P, J, 2) pixels."""
    h, w = ids.shape
    x, y = np.rint(np.nan_to_num(uv, nan=-1.0)).astype(int).transpose(2, 0, 1)  # (P, J) each
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    shown = ids[y.clip(0, h - 1), x.clip(0, w - 1)]  # (P, J)
    own = np.arange(len(uv))[:, None]
    return inside & (shown >= 0) & (shown != own)


def _scene(worker, index: int, rng: np.random.Generator, times: dict) -> tuple[dict, int]:
    """Scene ``index``: its row of every :data:`SCENE_ARRAYS` array, and the implausible
    poses replaced."""
    from rmpl.geometry.camera import project
    from rmpl.synth.body import place_bodies
    from rmpl.synth.cameras import sample_cameras
    from rmpl.synth.render import random_outfits

    cfg, V = worker.cfg, worker.cfg.views
    P = cfg.people[1]
    t0 = time.perf_counter()
    k = int(rng.integers(cfg.people[0], P + 1))
    verts, kps, meta, rejected = _draw_poses(worker, k, index * P, rng)
    verts, kps = place_bodies(verts, kps, rng.uniform(-np.pi, np.pi, k), spread(k, cfg.room, rng))
    center = kps[:, 11:13].mean(axis=(0, 1)).astype(float)  # the group's mean mid-hip
    K, R, t, size = (a[0] for a in sample_cameras(V, center[None], cfg.camera_preset, rng))
    if cfg.image_size:
        K, size = _scale_cameras(K, size, tuple(cfg.image_size))
    proj = project(kps[None].astype(float), K[:, None, None], R[:, None, None], t[:, None, None])
    colors = random_outfits(worker.body.vertex_parts, k, rng)
    t1 = time.perf_counter()
    images, ids = worker.renderer.render_scene(
        verts[None], colors[None], K[None], R[None], t[None], size[None], rng=rng
    )
    t2 = time.perf_counter()
    kp, sc = _detect_people_apart(worker.detector, images)  # (V, N, J, 2), (V, N, J)
    kp, sc = in_joint_set(worker.detector, kp, sc, cfg.joints)
    times["pose"] += t1 - t0
    times["render"] += t2 - t1
    times["detect"] += time.perf_counter() - t2

    def pad(a: np.ndarray, fill) -> np.ndarray:  # k bodies -> P slots
        return np.concatenate([a, np.full((P - k, *a.shape[1:]), fill, a.dtype)])

    present = np.arange(P) < k
    proj_p = np.stack([pad(proj[v], np.nan) for v in range(V)])  # (V, P, J, 2)
    phen, subject, clip, frame, mirrored = (np.asarray(x) for x in zip(*meta, strict=True))
    row = {
        "joints3d": pad(kps.astype(np.float32), np.nan),
        "present": present,
        "keypoints": kp.astype(np.float32),
        "scores": sc.astype(np.float32),
        "match": np.stack([match_detections(kp[v], sc[v], proj_p[v], present) for v in range(V)]),
        "projected": proj_p.astype(np.float32),
        "hidden": np.stack([_hidden(ids[v], proj_p[v]) for v in range(V)]),
        "K": K,
        "R": R,
        "t": t,
        "size": size.astype(np.int32),
        "phenotypes": pad(phen.astype(np.float32), 0.0),
        "subject": pad(subject.astype(str), ""),
        "clip": pad(clip.astype(str), ""),
        "frame": pad(frame.astype(np.int64), -1),
        "mirrored": pad(mirrored.astype(bool), False),
    }
    return row, rejected


def _detect_people_apart(detector, images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Every person the detector finds in images of unrelated scenes: keypoints (B, N, J, 2)
    and scores (B, N, J), N = its ``max_people`` (1 for a single-person detector)."""
    from rmpl.synth.detect import with_people_axis

    if not follows(detector):
        return with_people_axis(detector, *detector(images), len(images))
    parts = []
    for im in images:
        detector.reset()
        parts.append(with_people_axis(detector, *detector([im]), 1))
    return np.concatenate([k for k, _ in parts]), np.concatenate([s for _, s in parts])


def _scene_shard(worker, index: int, first: int, n: int, out: str | Path) -> dict:
    """Scenes ``first .. first + n - 1`` as shard ``index`` (see :func:`generate_shard`)."""
    cfg = worker.cfg
    times = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    parts: dict[str, list] = {k: [] for k in SCENE_ARRAYS}
    rejected = 0
    for i in range(first, first + n):
        rng = np.random.default_rng([cfg.seed, i, 3])  # a scene is the same in any shard
        row, bad = _scene(worker, i, rng, times)
        rejected += bad
        for key, value in row.items():
            parts[key].append(value)
    arrays = {k: np.stack(v) for k, v in parts.items()}
    found = arrays["scores"].max(-1) > 0  # (M, V, N)
    stats = {
        "shard": index,
        "scenes": n,
        "meshes": int(arrays["present"].sum()),
        "views": n * cfg.views,
        "rejected": rejected,
        "missed_joints": int((arrays["scores"] == 0).sum()),
        "missed_views": int((~found.any(-1)).sum()),
        "people_found": int(found.sum()),
        "people_matched": int((arrays["match"] >= 0).sum()),
        "seconds": times,
    }
    write_shard(shard_path(out, index), arrays, stats)
    return stats
