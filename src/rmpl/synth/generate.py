"""``rmpl generate``: the MHP dataset generator (thesis chapter 5), sharded and resumable.

One mesh = one anny body (random phenotype) posed from real motion (CMU ASF/AMC or BVH,
retargeted by :mod:`rmpl.synth.retarget`, mirrored and perturbed at random) or from the
random pose sampler, stood on the floor at a random place and heading, seen by ``views``
random cameras (:mod:`rmpl.synth.cameras`), rendered (:mod:`rmpl.synth.render`) and run
through a real 2D detector (:mod:`rmpl.synth.detect`). Its 3D COCO-17 joints come from the
mesh with anny's keypoint regressor, so targets and detections share the detector's joint
definitions.

Output directory::

    manifest.json           self-describing: config, counts, detector, joints, units, arrays
    poses.npz               the pose bank read from the motion folder (for resuming)
    shard_00000.npz ...     one compressed NPZ per ``shard_size`` meshes (see SHARD_ARRAYS)

Each shard is seeded by ``(seed, shard index)`` and written atomically, so a killed run
loses at most the shards in progress and running the same command again skips the
finished shards. Shape glossary: ``M`` meshes, ``V`` views, ``J`` joints (17).
"""

from __future__ import annotations

import json
import logging
import os
import time
import tomllib
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import COCO17

__all__ = [
    "GenerateConfig",
    "SHARD_ARRAYS",
    "generate",
    "generate_shard",
    "shard_path",
    "list_shards",
    "Worker",
]

log = logging.getLogger(__name__)

FORMAT = "rmpl.mhp.v1"

#: Arrays of a shard: name -> (shape, meaning).
SHARD_ARRAYS: dict[str, tuple[str, str]] = {
    "joints3d": ("(M, 17, 3) float32", "COCO-17 joints regressed from the mesh, world metres"),
    "keypoints": ("(M, V, 17, 2) float32", "detector keypoints, pixels, NaN = missed"),
    "scores": ("(M, V, 17) float32", "detector confidence in [0, 1], 0 = missed or outside"),
    "projected": ("(M, V, 17, 2) float32", "joints3d projected into each view, pixels"),
    "K": ("(M, V, 3, 3) float64", "intrinsics, pixels"),
    "R": ("(M, V, 3, 3) float64", "world-to-camera rotation"),
    "t": ("(M, V, 3) float64", "world-to-camera translation, metres"),
    "size": ("(M, V, 2) int32", "image (width, height), pixels"),
    "occluded": ("(M, V, 17) bool", "a black square was pasted over the joint"),
    "phenotypes": ("(M, 6) float32", "anny phenotypes (rmpl.synth.body.PHENOTYPES order)"),
    "subject": ("(M,) str", "source subject id ('random' for random poses)"),
    "clip": ("(M,) str", "source clip (path under the motion folder)"),
    "frame": ("(M,) int64", "source frame in the clip (-1 for random poses)"),
    "mirrored": ("(M,) bool", "the pose was mirrored left/right"),
}


@dataclass(frozen=True)
class GenerateConfig:
    """What ``rmpl generate`` makes; load with :meth:`from_toml`.

    Attributes:
        poses: a motion folder (CMU ASF/AMC, BVH; searched recursively), a pose bank
            ``.npz`` (:func:`rmpl.synth.retarget.save_pose_bank`), or ``"random"`` for
            :meth:`rmpl.synth.body.BodyModel.sample_poses`.
        subjects: keep only these motion subject ids (empty = all).
        exclude_subjects: drop these subject ids (e.g. ``["03"]``, held out).
        num_meshes: meshes (posed bodies), M.
        views: cameras per mesh, V (thesis: 20).
        camera_preset: ``h36m``, ``panoptic``, ``shelf`` or ``universal``.
        image_size: ``[width, height]`` for every view (the preset's camera is scaled to
            fit, centred), or empty for the preset's own sizes.
        detector: a key of :data:`rmpl.synth.detect.DETECTORS`, or ``"module:factory"``
            naming a callable that returns a :class:`rmpl.synth.detect.Detector`.
        seed: random seed; shard ``s`` uses ``(seed, s)``.
        shard_size: meshes per shard file.
        batch_size: meshes posed, rendered and detected together.
        mirror: probability of mirroring a pose left/right.
        perturb_deg: standard deviation of a random rotation of each driven bone, degrees.
        pose_fps: motion frames per second read before de-duplication.
        min_move: a motion frame is kept when some joint moved this far, metres, since the
            last kept frame of its clip (no near-duplicates).
        room: people stand uniformly within +-room metres of the room centre.
        min_age: phenotype age lower bound (0.5 is a teenager).
        occlusion_rate: probability that a black square covers a joint before detection
            (thesis 6.11.1); 0 = off.
        occlusion_size: side of the black squares, pixels.
        max_tries: implausible poses are replaced; give up after this many draws per mesh.
    """

    poses: str = "random"
    subjects: tuple[str, ...] = ()
    exclude_subjects: tuple[str, ...] = ()
    num_meshes: int = 100
    views: int = 20
    camera_preset: str = "universal"
    image_size: tuple[int, ...] = ()
    detector: str = "mediapipe"
    seed: int = 0
    shard_size: int = 50
    batch_size: int = 8
    mirror: float = 0.5
    perturb_deg: float = 3.0
    pose_fps: float = 10.0
    min_move: float = 0.05
    room: float = 1.0
    min_age: float = 0.5
    occlusion_rate: float = 0.0
    occlusion_size: int = 50
    max_tries: int = 10

    @classmethod
    def from_dict(cls, d: dict, path: str | Path | None = None) -> GenerateConfig:
        """Build and validate; errors name ``path`` and the field."""
        from rmpl.synth.cameras import CAMERA_PRESETS

        known = {f.name: f for f in fields(cls)}
        for key in d:
            if key not in known:
                raise InputError(path, key, f"one of the keys {sorted(known)}", "unknown key")
        d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        defaults = cls()
        for key, value in d.items():
            want = type(getattr(defaults, key))
            ok = isinstance(value, want) or (want is float and isinstance(value, int))
            if isinstance(value, bool) and want is not bool:
                ok = False
            if not ok:
                raise InputError(path, key, f"a {want.__name__}", repr(value))
            if want is float:
                d[key] = float(value)
        cfg = cls(**d)
        checks = [
            ("num_meshes", cfg.num_meshes >= 1, ">= 1"),
            ("views", cfg.views >= 1, ">= 1"),
            ("shard_size", cfg.shard_size >= 1, ">= 1"),
            ("batch_size", cfg.batch_size >= 1, ">= 1"),
            (
                "camera_preset",
                cfg.camera_preset in CAMERA_PRESETS,
                f"one of {sorted(CAMERA_PRESETS)}",
            ),
            (
                "image_size",
                cfg.image_size == ()
                or (
                    len(cfg.image_size) == 2
                    and all(isinstance(v, int) and v >= 32 for v in cfg.image_size)
                ),
                "[] or [width, height] in pixels (>= 32)",
            ),
            ("mirror", 0 <= cfg.mirror <= 1, "a probability in [0, 1]"),
            ("occlusion_rate", 0 <= cfg.occlusion_rate <= 1, "a probability in [0, 1]"),
            ("occlusion_size", cfg.occlusion_size >= 1, ">= 1 pixel"),
            ("perturb_deg", cfg.perturb_deg >= 0, ">= 0"),
            ("min_age", 0 <= cfg.min_age <= 1, "in [0, 1]"),
            ("max_tries", cfg.max_tries >= 1, ">= 1"),
            ("poses", bool(cfg.poses), "a motion folder, a pose bank .npz or 'random'"),
        ]
        for name, ok, expected in checks:
            if not ok:
                raise InputError(path, name, expected, repr(getattr(cfg, name)))
        return cfg

    @classmethod
    def from_toml(cls, path: str | Path, overrides: list[str] | None = None) -> GenerateConfig:
        """Read a TOML file; ``overrides`` are ``key=value`` strings (TOML values)."""
        path = Path(path)
        try:
            with open(path, "rb") as f:
                d = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise InputError(path, None, "valid TOML", e) from None
        for item in overrides or []:
            if "=" not in item:
                raise InputError(path, "--set", "key=value", repr(item))
            key, value = item.split("=", 1)
            try:
                d[key.strip()] = tomllib.loads(f"v = {value}")["v"]
            except tomllib.TOMLDecodeError:
                d[key.strip()] = value  # a bare string, e.g. --set poses=/data/cmu
        return cls.from_dict(d, path)

    @property
    def num_shards(self) -> int:
        return -(-self.num_meshes // self.shard_size)


def shard_path(out: str | Path, index: int) -> Path:
    return Path(out) / f"shard_{index:05d}.npz"


def list_shards(out: str | Path) -> list[Path]:
    """Finished shards of an output directory, sorted (temporary files are ignored)."""
    return sorted(p for p in Path(out).glob("shard_*.npz") if not p.name.startswith("."))


def _shard_ok(path: Path, meshes: int) -> bool:
    """Whether ``path`` is a finished shard of ``meshes`` meshes."""
    if not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as z:
            return set(SHARD_ARRAYS) <= set(z.files) and len(z["joints3d"]) == meshes
    except (OSError, ValueError, EOFError):
        return False


def _shard_meshes(cfg: GenerateConfig, index: int) -> int:
    return min(cfg.shard_size, cfg.num_meshes - index * cfg.shard_size)


# ------------------------------------------------------------------------ per-process work


def make_detector(name: str):
    """A detector from :data:`~rmpl.synth.detect.DETECTORS` or a ``module:factory`` spec."""
    from rmpl.synth.detect import DETECTORS

    if name in DETECTORS:
        return DETECTORS[name]()
    if ":" in name:
        import importlib

        module, attr = name.split(":", 1)
        return getattr(importlib.import_module(module), attr)()
    raise ValueError(f"unknown detector {name!r}; known: {sorted(DETECTORS)} or 'module:factory'")


class Worker:
    """One process's heavy state: body model, GL renderer, detector and pose bank.

    Args:
        cfg: the generator config.
        bank_path: the pose bank ``.npz`` (None for random poses).
        cache_dir: anny's cache directory (default ``$ANNY_CACHE_DIR``).
    """

    def __init__(
        self, cfg: GenerateConfig, bank_path: str | Path | None, cache_dir: str | None = None
    ) -> None:
        from rmpl.synth.body import BodyModel
        from rmpl.synth.render import Renderer
        from rmpl.synth.retarget import load_pose_bank

        self.cfg = cfg
        self.body = BodyModel(cache_dir=cache_dir or os.environ.get("ANNY_CACHE_DIR"))
        self.renderer = Renderer(self.body.faces, self.body.num_vertices)
        self.detector = make_detector(cfg.detector)
        self.bank = load_pose_bank(bank_path) if bank_path else None

    def close(self) -> None:
        self.renderer.close()
        close = getattr(self.detector, "close", None)
        if close is not None:
            close()


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


def _draw_poses(worker: Worker, n: int, first: int, rng: np.random.Generator):
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


def generate_shard(worker: Worker, index: int, out: str | Path) -> dict:
    """Make shard ``index`` and write it atomically; returns its counts and stage times."""
    cfg = worker.cfg
    first = index * cfg.shard_size
    n = _shard_meshes(cfg, index)
    if n <= 0:
        raise ValueError(f"shard {index} is beyond num_meshes={cfg.num_meshes}")
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
        kp2d, scores = worker.detector(images)
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
    path = shard_path(out, index)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays, stats=np.array(json.dumps(stats)))
    return stats


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


def _pose_batch(worker: Worker, b: int, first: int, rng: np.random.Generator) -> _Posed:
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


def _render_batch(worker: Worker, posed: _Posed, rng, occ_rng) -> tuple[list, np.ndarray]:
    """The b * V images (body-major), and the joints under a pasted square (b * V, 17)."""
    cfg = worker.cfg
    p, bv = posed, len(posed.joints) * cfg.views
    images = worker.renderer.render(p.vertices, p.colors, p.K, p.R, p.t, p.size, rng=rng)
    occ = np.zeros((bv, 17), bool)
    if cfg.occlusion_rate > 0:
        occ = occlude(
            images, p.projected.reshape(bv, 17, 2), cfg.occlusion_rate, cfg.occlusion_size, occ_rng
        )
    return images, occ


def _batch_arrays(posed: _Posed, kp2d, scores, occ: np.ndarray) -> dict[str, np.ndarray]:
    """One batch's part of every :data:`SHARD_ARRAYS` array, in their dtypes."""
    b, V = posed.K.shape[:2]
    phen, subject, clip, frame, mirrored = zip(*posed.meta, strict=True)
    return {
        "joints3d": posed.joints.astype(np.float32),
        "keypoints": np.asarray(kp2d, np.float32).reshape(b, V, 17, 2),
        "scores": np.asarray(scores, np.float32).reshape(b, V, 17),
        "projected": posed.projected.astype(np.float32),
        "K": posed.K,
        "R": posed.R,
        "t": posed.t,
        "size": posed.size.astype(np.int32),
        "occluded": occ.reshape(b, V, 17),
        "phenotypes": np.asarray(phen, np.float32),
        "subject": np.asarray(subject, str),
        "clip": np.asarray(clip, str),
        "frame": np.asarray(frame, np.int64),
        "mirrored": np.asarray(mirrored, bool),
    }


# --------------------------------------------------------------------------- the driver

_WORKER: Worker | None = None


def _init_pool(cfg_dict: dict, bank: str | None, cache_dir: str | None) -> None:
    global _WORKER
    os.environ.setdefault("LP_NUM_THREADS", "1")  # llvmpipe: one thread per worker
    import torch

    torch.set_num_threads(1)
    _WORKER = Worker(GenerateConfig(**cfg_dict), bank, cache_dir)


def _pool_shard(args: tuple[int, str]) -> dict:
    return generate_shard(_WORKER, args[0], args[1])


def _ray_shard(cfg_dict: dict, bank: str | None, cache_dir: str | None, index: int, out: str):
    """Ray task body: a worker state per Ray worker process, reused across its tasks."""
    global _WORKER
    if _WORKER is None or asdict(_WORKER.cfg) != cfg_dict:
        _init_pool(cfg_dict, bank, cache_dir)
    return generate_shard(_WORKER, index, out)


def _versions() -> dict[str, str]:
    from importlib import metadata

    out = {}
    for pkg in ("rmpl", "anny", "moderngl", "mediapipe", "numpy", "torch"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            pass
    return out


def _prepare_bank(cfg: GenerateConfig, out: Path) -> Path | None:
    """The pose bank file the workers read (built from a motion folder once)."""
    from rmpl.synth.retarget import PoseBank, build_pose_bank, load_pose_bank, save_pose_bank

    if cfg.poses == "random":
        return None
    src = Path(cfg.poses)
    target = out / "poses.npz"
    if target.is_file():
        return target
    if src.is_dir():
        bank = build_pose_bank(
            src,
            list(cfg.subjects) or None,
            cfg.exclude_subjects,
            fps=cfg.pose_fps,
            min_move=cfg.min_move,
        )
    elif src.is_file():
        bank = load_pose_bank(src)
        keep = np.ones(len(bank), bool)
        if cfg.subjects:
            keep &= np.isin(bank.subject, list(cfg.subjects))
        keep &= ~np.isin(bank.subject, list(cfg.exclude_subjects))
        bank = PoseBank(*(a[keep] for a in _bank_arrays(bank)))
        if not len(bank):
            raise InputError(src, "subjects", "poses of the selected subjects", "none")
    else:
        raise InputError(None, "poses", "a motion folder, a pose bank .npz or 'random'", src)
    return save_pose_bank(target, bank)


def _bank_arrays(bank) -> tuple[np.ndarray, ...]:
    return (bank.rotations, bank.rest_dirs, bank.joints, bank.subject, bank.clip, bank.frame)


def _write_manifest(out: Path, cfg: GenerateConfig, detector: str, extra: dict) -> None:
    manifest = {
        "format": FORMAT,
        "config": asdict(cfg),
        "detector": detector,
        "skeleton": "coco17",
        "joints": list(COCO17.joints),
        "units": {"3d": "metres", "2d": "pixels, pixel (i, j) centred on (i, j)"},
        "world": "z up, floor at z = 0",
        "camera_model": "x_cam = R X + t; pinhole K, no distortion",
        "arrays": {k: {"shape": s, "meaning": m} for k, (s, m) in SHARD_ARRAYS.items()},
        "num_shards": cfg.num_shards,
        "versions": _versions(),
        **extra,
    }
    with atomic_path(out / "manifest.json") as tmp:
        tmp.write_text(json.dumps(manifest, indent=2))


def _check_same_config(out: Path, cfg: GenerateConfig) -> None:
    path = out / "manifest.json"
    if not path.is_file():
        return
    old = json.loads(path.read_text()).get("config", {})
    new = json.loads(json.dumps(asdict(cfg)))
    # num_meshes may grow or shrink: shards are seeded by (seed, index) alone.
    diff = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k) and k != "num_meshes")
    if diff:
        raise InputError(
            path,
            diff[0],
            f"the same config as the existing run in {out} (to resume) or a new --out",
            f"{old.get(diff[0])!r} there, {new.get(diff[0])!r} now",
        )


def summarize(out: str | Path) -> dict:
    """Counts over the finished shards of ``out``."""
    totals = {
        "shards": 0,
        "meshes": 0,
        "views": 0,
        "rejected": 0,
        "missed_joints": 0,
        "missed_views": 0,
    }
    seconds = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    for p in list_shards(out):
        with np.load(p, allow_pickle=False) as z:
            s = json.loads(str(z["stats"]))
        totals["shards"] += 1
        for k in ("meshes", "views", "rejected", "missed_joints", "missed_views"):
            totals[k] += s[k]
        for k in seconds:
            seconds[k] += s["seconds"][k]
    return {**totals, "stage_seconds": seconds}


def generate(
    cfg: GenerateConfig,
    out: str | Path,
    workers: int = 1,
    ray_address: str | None = None,
    cache_dir: str | None = None,
    progress: bool = True,
) -> dict:
    """Generate (or resume) an MHP dataset into ``out``; returns the summary counts.

    Args:
        cfg: what to generate.
        out: output directory (created; resumed when it holds a run of the same config).
        workers: local worker processes (each with its own GL context and detector).
        ray_address: run the shards as Ray tasks on this cluster instead ("auto", an
            address, or "local" for a new local instance); ``out`` must be on a file system
            every Ray node sees.
        cache_dir: anny cache (default ``$ANNY_CACHE_DIR``).
        progress: show a tqdm bar over shards.
    """
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cache_dir = cache_dir or os.environ.get("ANNY_CACHE_DIR")
    _check_same_config(out, cfg)
    bank = _prepare_bank(cfg, out)
    bank_info = _bank_info(bank)
    _write_manifest(out, cfg, cfg.detector, {"status": "running", **bank_info})
    todo = [
        i for i in range(cfg.num_shards) if not _shard_ok(shard_path(out, i), _shard_meshes(cfg, i))
    ]
    done = cfg.num_shards - len(todo)
    if done:
        log.info("%s: %d of %d shards already done, resuming", out, done, cfg.num_shards)
    t0 = time.time()
    bar = tqdm(
        total=cfg.num_shards,
        initial=done,
        desc="shards",
        unit="shard",
        disable=not progress,
        dynamic_ncols=True,
    )
    runner = _run_on_ray if ray_address else _run_in_process if workers <= 1 else _run_in_pool
    new_views = 0
    if todo:
        new_views = runner(cfg, out, todo, bank, cache_dir, bar, workers, ray_address)
    bar.close()
    return _finish(cfg, out, bank_info, new_views, time.time() - t0, workers)


def _bank_info(bank: Path | None) -> dict:
    """The manifest's description of the pose bank: poses per subject."""
    if bank is None:
        return {}
    from rmpl.synth.retarget import load_pose_bank

    b = load_pose_bank(bank)
    subj, counts = np.unique(b.subject, return_counts=True)
    subjects = dict(zip(subj.tolist(), counts.tolist(), strict=True))
    return {"pose_bank": {"poses": len(b), "subjects": subjects}}


def _run_on_ray(
    cfg: GenerateConfig,
    out: Path,
    todo: list[int],
    bank: Path | None,
    cache_dir: str | None,
    bar,
    workers: int,
    ray_address: str | None,
) -> int:
    """Generate the shards ``todo`` as Ray tasks; returns the number of views made."""
    import ray

    if ray_address == "local":
        ray.init(num_cpus=max(workers, 1), include_dashboard=False, ignore_reinit_error=True)
    else:
        ray.init(address=ray_address, ignore_reinit_error=True)
    task = ray.remote(num_cpus=1)(_ray_shard)
    cfg_dict, bank_s = asdict(cfg), str(bank) if bank else None
    pending = [task.remote(cfg_dict, bank_s, cache_dir, i, str(out.resolve())) for i in todo]
    new_views = 0
    while pending:
        ready, pending = ray.wait(pending, num_returns=1)
        new_views += ray.get(ready[0])["views"]
        bar.update(1)
    return new_views


def _run_in_process(
    cfg: GenerateConfig,
    out: Path,
    todo: list[int],
    bank: Path | None,
    cache_dir: str | None,
    bar,
    workers: int,
    ray_address: str | None,
) -> int:
    """Generate the shards ``todo`` one after another in this process."""
    worker = Worker(cfg, bank, cache_dir)
    new_views = 0
    try:
        for i in todo:
            new_views += generate_shard(worker, i, out)["views"]
            bar.update(1)
    finally:
        worker.close()
    return new_views


def _run_in_pool(
    cfg: GenerateConfig,
    out: Path,
    todo: list[int],
    bank: Path | None,
    cache_dir: str | None,
    bar,
    workers: int,
    ray_address: str | None,
) -> int:
    """Generate the shards ``todo`` in ``workers`` local processes."""
    import multiprocessing as mp

    cfg_dict, bank_s = asdict(cfg), str(bank) if bank else None
    ctx = mp.get_context("spawn")  # fresh processes: one EGL context each
    new_views = 0
    with ctx.Pool(workers, _init_pool, (cfg_dict, bank_s, cache_dir)) as pool:
        for stats in pool.imap_unordered(_pool_shard, [(i, str(out)) for i in todo]):
            new_views += stats["views"]
            bar.update(1)
    return new_views


def _finish(
    cfg: GenerateConfig, out: Path, bank_info: dict, new_views: int, elapsed: float, workers: int
) -> dict:
    """Summarise the shards in ``out``, write the final manifest and log the run's rate."""
    summary = summarize(out)
    rate = new_views / elapsed if elapsed > 0 and new_views else 0.0
    summary["this_run"] = {
        "views": new_views,
        "seconds": round(elapsed, 1),
        "views_per_second": round(rate, 2),
        "workers": workers,
    }
    complete = summary["shards"] == cfg.num_shards
    _write_manifest(
        out,
        cfg,
        cfg.detector,
        {"status": "complete" if complete else "partial", "counts": summary, **bank_info},
    )
    log.info(
        "%s: %d meshes x %d views in %d shards (%d poses rejected); this run %d (mesh, view) "
        "samples in %.1f s = %.2f samples/s",
        out,
        summary["meshes"],
        cfg.views,
        summary["shards"],
        summary["rejected"],
        new_views,
        elapsed,
        rate,
    )
    return summary
