"""Methods compared on synthetic scenes of held-out motion (same 2D input for every method).

Two scene generators:

- :func:`evaluate_synthetic`: random camera setups (:class:`rmpl.data.synthetic.PairSource`,
  preset "universal"), V cameras per scene, the person anywhere in a room;
- :func:`evaluate_sphere`: the camera-geometry experiment (thesis 6.14): two cameras on a
  sphere around the person (:func:`rmpl.synth.cameras.sphere_cameras`) at a given height,
  the horizontal angle between them swept.

In both, 2D comes from the parametric detector model (:mod:`rmpl.synth.noise`), seeded, or
in :func:`evaluate_synthetic` from MHP renders with a real detector's output (``shards``);
keypoint dropout and calibration noise are applied identically to every method's input.

Shape glossary: ``B`` scenes, ``V`` views, ``J`` joints (COCO-17). Metres inside, mm out.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rmpl.data.mhp import ShardSource
from rmpl.data.synthetic import PairSource, SamplerConfig, perturb_extrinsics, place_poses
from rmpl.geometry.camera import Camera, Rig

__all__ = ["evaluate_synthetic", "evaluate_sphere"]

ALL_JOINTS = list(range(17))


def _per_scene(method, keypoints, scores, K, R, t) -> np.ndarray:
    """Run a rig-level method scene by scene (each scene has its own cameras): (B, 17, 3)
    COCO-17 (the first 17 joints of a HALPE-26 method), the joints scored."""
    B, V = scores.shape[:2]
    out = np.full((B, len(ALL_JOINTS), 3), np.nan)
    for i in range(B):
        if not (scores[i] > 0).any():
            continue
        rig = Rig(tuple(Camera(K[i, v], R[i, v], t[i, v], name=str(v)) for v in range(V)))
        out[i] = method(keypoints[i][None], scores[i][None], rig)[0][ALL_JOINTS]
    return out


def _dropout(kp, sc, p: float, rng: np.random.Generator):
    if p <= 0:
        return kp, sc
    drop = rng.random(sc.shape) < p
    return np.where(drop[..., None], np.nan, kp), np.where(drop, 0.0, sc)


def _row(pred: np.ndarray, target: np.ndarray, pck: float) -> dict[str, float]:
    from rmpl.evaluate.scoring import pose_metrics

    m = pose_metrics(pred, target, ALL_JOINTS, pck)
    return {k: m[k] for k in ("mpjpe", "kpstar", "coverage", "pa_mpjpe", "pck")}


def _common(preds: dict[str, np.ndarray]) -> np.ndarray:
    """Joints every method estimated, shape (B, J)."""
    return np.logical_and.reduce([np.isfinite(x).all(-1) for x in preds.values()])


def _masked_mpjpe(pred: np.ndarray, target: np.ndarray, mask: np.ndarray) -> float:
    """MPJPE (mm) over ``mask`` (B, J); NaN when it is empty."""
    e = np.linalg.norm(pred - target, axis=-1)[mask]
    return 1000 * float(e.mean()) if e.size else float("nan")


def evaluate_synthetic(
    poses: np.ndarray,
    methods: dict,
    view_counts: Sequence[int],
    samples: int = 2000,
    seed: int = 7,
    dropout: Sequence[float] = (0.0,),
    calib_noise: tuple[float, float] | None = None,
    calib_reps: int = 1,
    pck_threshold: float = 0.150,
    progress: bool = True,
    predictions: dict | None = None,
    shards: str | Path | None = None,
) -> list[dict]:
    """MPJPE, KP* MPJPE, PA-MPJPE (mm), PCK and coverage (%) per method and view count.

    Args:
        poses: held-out COCO-17 poses, shape (N, 17, 3), metres, z up (ignored with
            ``shards``).
        methods: name -> method (see :func:`rmpl.evaluate.methods.make_method`).
        view_counts: numbers of cameras per scene.
        samples: scenes per view count (and condition).
        seed: seed of the scenes, the 2D noise, the dropout masks and calibration noise.
        dropout: keypoint removal probabilities (applied after the noise model).
        calib_noise: (degrees, metres) extrinsic noise given to the methods, or None. When
            set, each view count gets a clean and a noisy row per dropout value.
        calib_reps: independent noise draws averaged (each draws its own scenes).
        pck_threshold: metres.
        progress: tqdm progress bar.
        predictions: if a dict, filled with (views, dropout, calib, method) ->
            (pred, target), each (B, 17, 3) metres, for per-joint breakdowns.
        shards: an MHP directory (``rmpl generate``) to take the scenes from instead: each
            scene is one rendered mesh seen by ``v`` of its views drawn at random, with the
            real detector's 2D (no noise model); make it from held-out motion.

    Returns:
        Rows: views, method, mpjpe, kpstar, coverage, pa_mpjpe, pck, mpjpe_common (on the
        joints every method estimated), dropout, calib_noise.
    """
    from tqdm import tqdm

    calibs = [None] if calib_noise is None else [None, calib_noise]
    jobs = [(v, p, c) for v in view_counts for c in calibs for p in dropout]
    rows = []
    for ji, (v, p, calib) in enumerate(tqdm(jobs, desc="synthetic", disable=not progress)):
        reps = calib_reps if calib is not None else 1
        merged = _run_condition(poses, shards, methods, samples, seed, ji, v, p, calib, reps)
        common = _common({n: a for n, (a, _) in merged.items()})
        for name, (pred, target) in merged.items():
            if predictions is not None:
                predictions[v, p, calib, name] = (pred, target)
            row = {"views": v, "method": name, **_row(pred, target, pck_threshold)}
            row["mpjpe_common"] = _masked_mpjpe(pred, target, common)
            row["dropout"] = p
            row["calib_noise"] = (
                "none" if calib is None else (f"{calib[0]:g} deg, {1000 * calib[1]:g} mm")
            )
            rows.append(row)
    return rows


def _run_condition(poses, shards, methods, samples, seed, ji, v, p, calib, reps):
    """Every method on the scenes of one view count and condition, ``reps`` draws.

    Returns:
        name -> (predictions, targets), each (B, 17, 3) metres over every draw.
    """
    results: dict[str, list] = {m: [] for m in methods}
    for r in range(reps):
        # The same scenes for every condition of one view count (seeded by v and rep).
        if shards is not None:
            src = ShardSource(shards, drop_rate=0.0, augment=False, seed=[seed, v, r])
        else:
            src = PairSource(poses, SamplerConfig(drop_rate=0.0), seed=[seed, v, r])
        batch = src.batch(samples, v, train=False)
        rng = np.random.default_rng([seed, 99, ji, r])
        kp, sc = _dropout(batch.keypoints, batch.scores.astype(float), p, rng)
        R, t = batch.R, batch.t
        if calib is not None:
            R, t = perturb_extrinsics(R, t, calib[0], calib[1], rng)
        target = batch.target[:, ALL_JOINTS].astype(float)  # COCO-17, the scored joints
        for name, method in methods.items():
            pred = _per_scene(method, kp, sc, batch.K, R, t)
            results[name].append((pred, target))
    return {
        name: (np.concatenate([a for a, _ in pairs]), np.concatenate([b for _, b in pairs]))
        for name, pairs in results.items()
    }


def evaluate_sphere(
    poses: np.ndarray,
    methods: dict,
    heights: Sequence[float],
    angles: Sequence[float],
    samples: int = 300,
    seed: int = 7,
    radius: float = 6.0,
    center_height: float = 1.0,
    pck_threshold: float = 0.150,
    progress: bool = True,
) -> list[dict]:
    """The camera-geometry sweep: two cameras on a sphere, angle between them swept.

    Every scene puts one held-out pose (random turn about z, mirror and size as in
    training) with its mid-hip above the origin; the two cameras sit ``radius`` metres
    from (0, 0, ``center_height``) at an absolute height, at azimuths -angle/2 and
    +angle/2, aimed at that point (Human3.6M-like intrinsics, 1000 x 1000 px). The same
    scenes and noise draws are used for every height and angle.

    Returns:
        Rows: height, angle, method, mpjpe, kpstar, coverage, pa_mpjpe, pck, mpjpe_common
        (mm, %; the last on the joints every method estimated).
    """
    from tqdm import tqdm

    from rmpl.synth.cameras import sphere_cameras
    from rmpl.synth.noise import detect_like

    rng = np.random.default_rng([seed, 6, 14])
    idx = rng.integers(0, len(poses), samples)
    joints = place_poses(np.asarray(poses, float)[idx], rng, SamplerConfig(room=0.0, drop_rate=0.0))
    rows = []
    jobs = [(h, a) for h in heights for a in angles]
    for h, a in tqdm(jobs, desc="sphere", disable=not progress):
        K, R, t, wh = sphere_cameras(
            h, [-a / 2, a / 2], radius=radius, center=(0.0, 0.0, center_height)
        )
        rig = Rig(tuple(Camera(K[v], R[v], t[v], size=tuple(wh[v]), name=str(v)) for v in (0, 1)))
        B = samples
        kp, sc = detect_like(
            joints,
            np.broadcast_to(K, (B, 2, 3, 3)),
            np.broadcast_to(R, (B, 2, 3, 3)),
            np.broadcast_to(t, (B, 2, 3)),
            np.broadcast_to(wh, (B, 2, 2)),
            np.random.default_rng([seed, 61]),  # the same noise draws at every point
        )
        preds = {name: method(kp, sc, rig)[..., ALL_JOINTS, :] for name, method in methods.items()}
        common = _common(preds)
        for name, pred in preds.items():
            row = {"height": float(h), "angle": float(a), "method": name}
            row |= _row(pred, joints, pck_threshold)
            row["mpjpe_common"] = _masked_mpjpe(pred, joints, common)
            rows.append(row)
    return rows
