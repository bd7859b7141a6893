"""The driver: shards in one process, a process pool or on Ray; the manifest; resuming.

Part of :mod:`rmpl.synth.generate` (``rmpl generate``).
"""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import SKELETONS
from rmpl.synth.generate.config import (
    GenerateConfig,
    _config_dict,
    _shard_meshes,
    shard_arrays,
)
from rmpl.synth.generate.sequences import build_motion_bank, load_motion_bank, save_motion_bank
from rmpl.synth.generate.worker import Worker, generate_shard
from rmpl.synth.shards import (
    FORMAT,
    SCENE_FORMAT,
    SEQUENCE_FORMAT,
    list_shards,
    shard_ok,
    shard_path,
)

log = logging.getLogger(__name__)

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
    if cfg.sequences:
        return _prepare_motion(cfg, out)
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


def _prepare_motion(cfg: GenerateConfig, out: Path) -> Path:
    """The motion bank the workers of a sequence run read (``out/motion.npz``, built once
    from a motion folder, or the subjects' segments of a given ``motion.npz``)."""
    src, target = Path(cfg.poses), out / "motion.npz"
    if target.is_file():
        bank = load_motion_bank(target)
    elif src.is_dir():
        bank = build_motion_bank(src, list(cfg.subjects) or None, cfg.exclude_subjects)
    elif src.is_file():
        bank = load_motion_bank(src)
        subj = bank.subjects[bank.clip_index]
        keep = ~np.isin(subj, list(cfg.exclude_subjects))
        if cfg.subjects:
            keep &= np.isin(subj, list(cfg.subjects))
        bank = bank.select(keep)
        if not len(bank):
            raise InputError(src, "subjects", "motion of the selected subjects", "none")
    else:
        raise InputError(None, "poses", "a motion folder or a motion.npz", src)
    longest = int(bank.length.max())
    if longest < cfg.sequence_frames:
        raise InputError(
            src,
            "sequence_frames",
            f"at most the longest clean motion segment ({longest} frames)",
            cfg.sequence_frames,
        )
    return target if target.is_file() else save_motion_bank(target, bank)


def _bank_arrays(bank) -> tuple[np.ndarray, ...]:
    return (bank.rotations, bank.rest_dirs, bank.joints, bank.subject, bank.clip, bank.frame)


def _write_manifest(out: Path, cfg: GenerateConfig, detector: str, extra: dict) -> None:
    manifest = {
        "format": SEQUENCE_FORMAT if cfg.sequences else SCENE_FORMAT if cfg.scenes else FORMAT,
        "config": _config_dict(cfg),
        "detector": detector,
        "skeleton": cfg.joints,
        "joints": list(SKELETONS[cfg.joints].joints),
        "units": {"3d": "metres", "2d": "pixels, pixel (i, j) centred on (i, j)"},
        "world": "z up, floor at z = 0",
        "camera_model": "x_cam = R X + t; pinhole K, no distortion",
        "arrays": {k: {"shape": s, "meaning": m} for k, (s, m) in shard_arrays(cfg).items()},
        "num_shards": cfg.num_shards,
        "versions": _versions(),
        **extra,
    }
    if cfg.scenes:
        manifest["scenes"] = {
            "people": list(cfg.people),
            "views": cfg.views,
            "detections": "every person the detector finds per image (N slots, unassociated); "
            "match pairs them with the bodies by the projected joints",
            "spacing": "mid-hips at least 0.6 m apart on the floor; cameras aimed at the "
            "group's mean mid-hip",
        }
    if cfg.sequences:
        manifest["sequences"] = {
            "frames": cfg.sequence_frames,
            "views": cfg.views,
            "fps_range": list(cfg.sequence_fps),
            "speed_range": list(cfg.sequence_speed),
            "detector_mode": "a detector that follows people (blazepose-multi) sees each "
            "view's frames in order as one video; any other (mediapipe: static-image mode) "
            "detects every image afresh; the most confident person per image is kept",
            "per_sequence": "one body (phenotype, outfit, lighting), one motion window, one rig",
        }
    with atomic_path(out / "manifest.json") as tmp:
        tmp.write_text(json.dumps(manifest, indent=2))


def _check_same_config(out: Path, cfg: GenerateConfig) -> None:
    path = out / "manifest.json"
    if not path.is_file():
        return
    old = json.loads(path.read_text()).get("config", {})
    new = json.loads(json.dumps(_config_dict(cfg)))
    # num_meshes may grow or shrink: shards are seeded by (seed, index) alone.
    diff = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k) and k != "num_meshes")
    if "sequence_frames" in diff:  # sequences or not, and how long: the first thing to say
        diff.remove("sequence_frames")
        diff.insert(0, "sequence_frames")
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
    extra: dict[str, int] = {}  # counts only sequence or scene shards have
    for p in list_shards(out):
        with np.load(p, allow_pickle=False) as z:
            s = json.loads(str(z["stats"]))
        totals["shards"] += 1
        for k in ("meshes", "views", "rejected", "missed_joints", "missed_views"):
            totals[k] += s[k]
        for k in seconds:
            seconds[k] += s["seconds"][k]
        for k in ("sequences", "scenes", "people_found", "people_matched"):
            if k in s:
                extra[k] = extra.get(k, 0) + s[k]
    # A sequence set's meshes are its frames, its views its renders; a scene set's meshes
    # are its bodies, its views its images.
    return {**totals, **extra, "stage_seconds": seconds}


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
    arrays = shard_arrays(cfg)
    todo = [
        i
        for i in range(cfg.num_shards)
        if not shard_ok(shard_path(out, i), _shard_meshes(cfg, i), arrays)
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
    """The manifest's description of the pose bank: poses per subject (or, for a motion
    bank, its segments and seconds per subject)."""
    if bank is None:
        return {}
    if bank.name == "motion.npz":
        m = load_motion_bank(bank)
        return {
            "motion": {
                "segments": len(m),
                "frames": int(m.length.sum()),
                "seconds_per_subject": m.seconds_per_subject(),
            }
        }
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
    what = f"{summary['meshes']} meshes"
    if cfg.sequences:
        what = f"{summary['sequences']} sequences x {cfg.sequence_frames} frames"
    elif cfg.scenes:
        what = f"{summary['scenes']} scenes of {summary['meshes']} bodies"
    log.info(
        "%s: %s x %d views in %d shards (%d %s rejected); this run %d (mesh, view) "
        "samples in %.1f s = %.2f samples/s",
        out,
        what,
        cfg.views,
        summary["shards"],
        summary["rejected"],
        "sequences" if cfg.sequences else "poses",
        new_views,
        elapsed,
        rate,
    )
    return summary
