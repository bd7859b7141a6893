"""Training the lifter (thesis 6.3 / 6.11 / 6.13), resumable, with atomic checkpoints.

The recipe: Adam with weight decay, lr steps x0.1 at 50 % and 75 % of training, MPJPE loss,
a random number of views per batch, random keypoint removal, optional calibration noise.

A run directory holds ``model.safetensors`` + ``config.json`` (a self-describing checkpoint
that :class:`rmpl.Lifter` loads), ``state.pt`` (optimizer, step, RNG: for resuming) and
``log.jsonl`` (one line per validation). Killing a run loses at most the steps since the
last checkpoint; running the same command again resumes.
"""

from __future__ import annotations

import json
import logging
import math
import time
import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import torch

from rmpl.data.synthetic import PairSource, SamplerConfig
from rmpl.errors import InputError
from rmpl.geometry.triangulate import _dlt
from rmpl.io.atomic import atomic_path
from rmpl.model.checkpoint import load_checkpoint, write_checkpoint
from rmpl.model.lifter import PRESETS, RMPL, RMPLConfig, build_model, camera_features
from rmpl.skeleton import KP_STAR, skeleton_for
from rmpl.synth.noise import NoiseConfig

__all__ = ["TrainConfig", "train", "save_checkpoint", "load_checkpoint", "validation_sets"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainConfig:
    """Everything a training run needs; load with :meth:`from_toml`.

    Attributes:
        poses: path to a pose bank (``.npz`` from ``rmpl poses``) or a motion directory.
        holdout: subjects kept out of training, used for validation.
        preset: architecture preset (see :data:`rmpl.model.PRESETS`).
        model: overrides of the preset's :class:`RMPLConfig` fields.
        steps: optimizer steps.
        batch_size: samples per step.
        lr: initial learning rate (x0.1 at 50 % and 75 % of the steps).
        weight_decay: Adam weight decay.
        min_views, max_views: each batch has a number of views drawn in this range.
        single_view_rate: probability of a one-view batch (when min_views is 1).
        single_view_weight: loss weight of one-view batches. Their depth is ambiguous and
            their error ~20x larger; at full weight they swamp the multi-view signal.
        val_every: steps between validations and checkpoints.
        val_size: samples per validation view count.
        seed: random seed.
        threads: torch CPU threads.
        sampler: :class:`SamplerConfig` overrides.
        noise: :class:`NoiseConfig` overrides (applied over ``noise_file``).
        noise_file: a TOML file with a ``[noise]`` table, e.g. the detector noise fitted to
            MHP renders by ``rmpl generate --stats DIR`` (``DIR/noise.toml``); "" = the
            defaults. The parametric validation set uses the same noise model.
        time_limit: stop (with a checkpoint) after this many seconds of this invocation.
        mhp: MHP shard directories (``rmpl generate``) to train on; empty = parametric
            pairs only. Meshes posed from ``holdout`` subjects are left out.
        mhp_weight: probability that a batch comes from ``mhp`` rather than from the
            parametric source (1 = MHP only).
        mhp_val: an MHP directory for a second validation (``mhp_kpstar_*`` in the log):
            renders of held-out motion with their real detections (all of its meshes are
            used: make it from the ``holdout`` subjects only).
        init: a checkpoint directory whose weights start the run (a fine-tune). Its joint
            set may be smaller than the model's (COCO-17 into HALPE-26): each new joint's
            identity token starts as that of the joint it hangs from
            (:data:`INIT_FROM`); inputs it lacks (the floor's) start with zero weights.
            "" = random initialisation.
    """

    poses: str = ""
    holdout: tuple[str, ...] = ("03",)
    preset: str = "small"
    model: dict = field(default_factory=dict)
    steps: int = 20000
    batch_size: int = 128
    lr: float = 1e-4
    weight_decay: float = 1e-4
    min_views: int = 1
    max_views: int = 5
    single_view_rate: float = 0.1
    single_view_weight: float = 0.1
    val_every: int = 500
    val_size: int = 512
    seed: int = 0
    threads: int = 2
    sampler: dict = field(default_factory=dict)
    noise: dict = field(default_factory=dict)
    noise_file: str = ""
    time_limit: float = 0.0
    mhp: tuple[str, ...] = ()
    mhp_weight: float = 1.0
    mhp_val: str = ""
    init: str = ""

    @classmethod
    def from_dict(cls, d: dict) -> TrainConfig:
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(
                f"unknown training config keys {sorted(unknown)}; known: {sorted(known)}"
            )
        d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        cfg = cls(**d)
        if cfg.preset not in PRESETS:
            raise ValueError(f"unknown preset {cfg.preset!r}; choose from {sorted(PRESETS)}")
        cfg.model_config()  # validates overrides
        SamplerConfig(**cfg.sampler)
        cfg.noise_config()
        if cfg.mhp and not 0 < cfg.mhp_weight <= 1:
            raise ValueError(f"mhp_weight must be in (0, 1], got {cfg.mhp_weight}")
        if not 1 <= cfg.min_views <= cfg.max_views:
            raise ValueError(
                f"need 1 <= min_views <= max_views, got {cfg.min_views}, {cfg.max_views}"
            )
        return cfg

    @classmethod
    def from_toml(cls, path: str | Path, overrides: list[str] | None = None) -> TrainConfig:
        """Read a TOML file; ``overrides`` are ``key=value`` strings (TOML values)."""
        with open(path, "rb") as f:
            d = tomllib.load(f)
        return cls.from_dict(apply_overrides(d, overrides))

    def noise_config(self) -> NoiseConfig:
        """The detector noise model: ``noise_file``'s ``[noise]`` table, then ``noise``."""
        table = {}
        if self.noise_file:
            path = Path(self.noise_file)
            try:
                with open(path, "rb") as f:
                    doc = tomllib.load(f)
            except OSError as e:
                raise InputError(path, None, "a readable TOML file", e.strerror) from None
            except tomllib.TOMLDecodeError as e:
                raise InputError(path, None, "valid TOML", str(e)) from None
            table = doc.get("noise")
            if not isinstance(table, dict):
                raise InputError(path, "noise", "a [noise] table (rmpl generate --stats)", None)
        try:
            return NoiseConfig.from_dict({**table, **self.noise})
        except (TypeError, ValueError) as e:
            where = self.noise_file or None
            raise InputError(where, "noise", "NoiseConfig fields", str(e)) from None

    def model_config(self) -> RMPLConfig:
        base = PRESETS[self.preset]
        return RMPLConfig.from_dict({**base.to_dict(), **self.model})


def apply_overrides(d: dict, overrides: list[str] | None) -> dict:
    """``key=value`` strings (TOML values; ``a.b=...`` for a table's key) applied to ``d``."""
    for item in overrides or []:
        if "=" not in item:
            raise ValueError(f"override must be key=value, got {item!r}")
        key, value = item.split("=", 1)
        parsed = tomllib.loads(f"v = {value}")["v"] if value else ""
        target = d
        *parents, leaf = key.split(".")
        for p in parents:
            target = target.setdefault(p, {})
        target[leaf] = parsed
    return d


def save_checkpoint(model: RMPL, path: str | Path, extra: dict | None = None) -> None:
    """Write ``model.safetensors`` and ``config.json`` into directory ``path``, atomically."""
    meta = {
        "format": "rmpl-checkpoint-1",
        "model": model.config.to_dict(),
        "skeleton": model.config.skeleton,
        "joints": list(skeleton_for(model.config.skeleton).joints),
        "units": "metres",
        **(extra or {}),
    }
    write_checkpoint(model, path, meta)


def validation_sets(
    poses: np.ndarray, cfg: TrainConfig, views=(1, 2, 3, 4, 5)
) -> dict[int, object]:
    """Fixed validation batches per number of views (seeded, no keypoint removal; a floor
    the model may read is given for every sample)."""
    sampler = SamplerConfig(**cfg.sampler)
    sampler = replace(sampler, drop_rate=0.0, floor_rate=float(sampler.floor_rate > 0))
    src = PairSource(poses, sampler, cfg.noise_config(), seed=12345)
    return {v: src.batch(cfg.val_size, v, train=False) for v in views}


def _training_source(cfg: TrainConfig, poses_train: np.ndarray):
    """The parametric pair source, MHP shards, or a mix of both (see ``mhp_weight``)."""
    sampler = SamplerConfig(**cfg.sampler)
    pairs = PairSource(poses_train, sampler, cfg.noise_config(), cfg.seed)
    if not cfg.mhp:
        return pairs
    from rmpl.data.mhp import MixSource, ShardSource

    shards = ShardSource(
        list(cfg.mhp),
        exclude_subjects=cfg.holdout,
        drop_rate=sampler.drop_rate,
        seed=cfg.seed,
        joints=cfg.model_config().skeleton,
        floor=_shard_floor(sampler),
    )
    log.info("MHP: %d meshes x up to %d views", shards.num_meshes, shards.num_views)
    if shards.num_views < cfg.max_views:
        raise InputError(
            ", ".join(cfg.mhp),
            "views per mesh",
            f"at least max_views = {cfg.max_views} (or lower max_views)",
            shards.num_views,
        )
    if cfg.mhp_weight >= 1:
        return shards
    return MixSource([shards, pairs], [cfg.mhp_weight, 1 - cfg.mhp_weight], seed=cfg.seed)


def _shard_floor(sampler: SamplerConfig) -> tuple[float, float, float] | None:
    """MHP renders stand on z = 0: their floor as the sampler gives it (``ShardSource``)."""
    if sampler.floor_rate <= 0:
        return None
    return (sampler.floor_rate, sampler.floor_noise_m, sampler.floor_tilt_deg)


def _mhp_validation_sets(cfg: TrainConfig, views=(1, 2, 3, 4, 5)) -> dict[int, object]:
    """Fixed batches of held-out MHP renders (no augmentation, no keypoint removal; a floor
    the model may read is given for every sample)."""
    if not cfg.mhp_val:
        return {}
    from rmpl.data.mhp import ShardSource

    floor = (1.0, 0.0, 0.0) if SamplerConfig(**cfg.sampler).floor_rate > 0 else None
    src = ShardSource(
        cfg.mhp_val, drop_rate=0.0, augment=False, seed=54321,
        joints=cfg.model_config().skeleton, floor=floor,
    )  # fmt: skip
    return {v: src.batch(cfg.val_size, v, train=False) for v in views if v <= src.num_views}


def _triangulation_mpjpe(batch) -> float:
    """Confidence-weighted DLT on a validation batch, KP* MPJPE (mm) on triangulable joints."""
    from rmpl.geometry.rays import pixel_to_normalized

    ok = batch.scores > 0
    xy = pixel_to_normalized(
        np.where(ok[..., None], batch.keypoints, 0.0), batch.K[:, :, None], None
    )
    P = np.concatenate([batch.R, batch.t[..., None]], -1)
    X = _dlt(xy, P, np.where(ok, batch.scores, 0.0))
    e = np.linalg.norm(X - batch.target, axis=-1)[:, list(KP_STAR)]
    return float(np.nanmean(e) * 1000) if np.isfinite(e).any() else float("nan")


def forward_batch(model: torch.nn.Module, b) -> torch.Tensor:
    """Run a model on a :class:`~rmpl.data.synthetic.Batch`, with the inputs its config asks
    for (rays, or pixels [+ calibration] for the modality ablation): (B, J, 3)."""
    rays, scores = torch.from_numpy(b.rays), torch.from_numpy(b.scores)
    if getattr(model.config, "floor", False):
        floor = getattr(b, "floor", None)
        return model(rays, scores, floor=None if floor is None else torch.from_numpy(floor))
    if model.config.inputs == "rays":
        return model(rays, scores)
    kp = torch.from_numpy(np.nan_to_num(b.keypoints).astype(np.float32))
    cams = camera_features(*(torch.from_numpy(np.asarray(a, np.float32)) for a in (b.K, b.R, b.t)))
    return model(rays, scores, kp, cams)


@torch.no_grad()
def evaluate_batches(model: RMPL, sets: dict) -> dict[str, float]:
    """KP* MPJPE (mm) of the model per number of views, and on triangulable joints."""
    model.eval()
    out = {}
    for v, b in sets.items():
        pred = forward_batch(model, b).numpy()
        e = np.linalg.norm(pred - b.target, axis=-1)
        out[f"mpjpe_{v}v"] = float(np.nanmean(e[:, :17]) * 1000)  # COCO-17, as before
        out[f"kpstar_{v}v"] = float(e[:, list(KP_STAR)].mean() * 1000)
        if e.shape[1] > 17 and np.isfinite(e[:, 17:]).any():
            out[f"extra_{v}v"] = float(np.nanmean(e[:, 17:]) * 1000)  # head top .. heels
    model.train()
    return out


def _lr_at(step: int, cfg: TrainConfig) -> float:
    warmup = min(500, cfg.steps // 20)
    f = min(1.0, (step + 1) / max(warmup, 1))
    if step >= 0.75 * cfg.steps:
        f *= 0.01
    elif step >= 0.5 * cfg.steps:
        f *= 0.1
    return cfg.lr * f


@dataclass
class _Progress:
    """What a resumed run continues from: the step, the time spent, the running loss."""

    step: int = 0
    elapsed: float = 0.0
    running: float | None = None


def _resume(out: Path, model, opt, src, rng_views, seed: int) -> _Progress:
    """Restore the state of ``out/state.pt`` (model, optimizer, every RNG), and drop the log
    records after it (a kill between a logged validation and its checkpoint)."""
    state_file = out / "state.pt"
    progress = _Progress()
    if state_file.exists():
        try:
            state = torch.load(state_file, weights_only=False)
        except Exception as e:  # noqa: BLE001 - torch raises many kinds for a damaged file
            raise InputError(
                state_file, None, "a training state written by rmpl train", e
            ) from None
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        src.rng.bit_generator.state = state["rng"]
        if "rng_views" in state:  # states before 0.1.1 re-seeded these (not bit-identical)
            rng_views.bit_generator.state = state["rng_views"]
            torch.set_rng_state(state["torch_rng"])
        else:
            rng_views.bit_generator.state = np.random.default_rng(
                seed + state["step"]
            ).bit_generator.state
        progress = _Progress(state["step"], state.get("elapsed", 0.0), state.get("running"))
        log.info("resuming %s at step %d", out, progress.step)
    _truncate_log(out / "log.jsonl", progress.step)
    return progress


def _truncate_log(path: Path, step: int) -> None:
    """Keep the records of steps up to ``step`` (the checkpoint a run resumes from)."""
    if not path.exists():
        return
    lines = path.read_text().splitlines()
    keep = []
    for line in lines:
        try:
            record = json.loads(line)
        except ValueError:  # a line cut by a kill
            continue
        if isinstance(record, dict) and record.get("step", math.inf) <= step:
            keep.append(line)
    if len(keep) != len(lines):
        log.warning("%s: dropping %d records after step %d", path, len(lines) - len(keep), step)
        with atomic_path(path) as tmp:
            tmp.write_text("".join(line + "\n" for line in keep))


def _validation(cfg: TrainConfig, poses_val: np.ndarray):
    """The fixed validation batches (parametric and MHP) and triangulation's errors on them."""
    sets = validation_sets(poses_val, cfg)
    tri = {f"triangulation_kpstar_{v}v": _triangulation_mpjpe(b) for v, b in sets.items() if v > 1}
    mhp_sets = _mhp_validation_sets(cfg)
    tri |= {
        f"mhp_triangulation_kpstar_{v}v": _triangulation_mpjpe(b)
        for v, b in mhp_sets.items()
        if v > 1
    }
    return sets, mhp_sets, tri


def _num_views(cfg: TrainConfig, rng: np.random.Generator) -> int:
    if cfg.min_views == 1 and rng.random() < cfg.single_view_rate:
        return 1
    return int(rng.integers(max(cfg.min_views, 2), cfg.max_views + 1))


def _train_step(model, opt, b, cfg: TrainConfig, step: int, V: int) -> float:
    """One optimizer step on batch ``b``; returns the loss (metres)."""
    for g in opt.param_groups:
        g["lr"] = _lr_at(step, cfg)
    pred = forward_batch(model, b)
    loss = joint_loss(pred, torch.from_numpy(b.target))
    if not torch.isfinite(loss):
        raise RuntimeError(f"non-finite loss at step {step}; stopping without saving")
    opt.zero_grad(set_to_none=True)
    (loss * (cfg.single_view_weight if V == 1 else 1.0)).backward()
    torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
    opt.step()
    return loss.item()


def joint_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean Euclidean joint error (metres) over the joints with a target: NaN targets (a
    COCO-17 set read as HALPE-26) are left out."""
    ok = torch.isfinite(target).all(-1)
    err = (pred - torch.nan_to_num(target)).norm(dim=-1)
    if bool(ok.all()):
        return err.mean()
    return (err * ok).sum() / ok.sum().clamp(min=1)


#: For :attr:`TrainConfig.init`: the joint whose identity token a new joint starts from.
INIT_FROM: dict[str, str] = {
    "head_top": "nose",
    "neck": "nose",
    "mid_hip": "left_hip",
    "left_big_toe": "left_ankle",
    "right_big_toe": "right_ankle",
    "left_small_toe": "left_ankle",
    "right_small_toe": "right_ankle",
    "left_heel": "left_ankle",
    "right_heel": "right_ankle",
}


def init_from_checkpoint(model: RMPL, path: str | Path) -> None:
    """Copy a checkpoint's weights into ``model`` (see :attr:`TrainConfig.init`)."""
    src, _ = load_checkpoint(path)
    have, want = skeleton_for(src.config.skeleton), skeleton_for(model.config.skeleton)
    state = src.state_dict()
    anatomy = model.anatomy.detach().clone()
    for j, name in enumerate(want.joints):
        source = name if name in have.joints else INIT_FROM.get(name)
        if source is None or source not in have.joints:
            raise InputError(path, "joints", f"the joints of {want.name}", have.name)
        anatomy[0, j] = state["anatomy"][0, have.index(source)]
    state["anatomy"] = anatomy
    for key, want_t in model.state_dict().items():  # inputs the source lacks (the floor)
        have_t = state.get(key)
        if (
            have_t is not None and have_t.ndim == 2 and want_t.ndim == 2
            and have_t.shape[0] == want_t.shape[0] and have_t.shape[1] < want_t.shape[1]
        ):  # fmt: skip
            wider = torch.zeros_like(want_t)
            wider[:, : have_t.shape[1]] = have_t
            state[key] = wider  # new input columns start at zero: the same answers at first
    try:
        model.load_state_dict(state)
    except RuntimeError as e:
        raise InputError(path, "model", "the architecture of this run's model", e) from None


def _save_state(out: Path, model, opt, src, rng_views, progress: _Progress) -> None:
    with atomic_path(out / "state.pt") as tmp:
        torch.save(
            {
                "model": model.state_dict(),
                "optimizer": opt.state_dict(),
                "step": progress.step,
                "elapsed": progress.elapsed,
                "running": progress.running,
                "rng": src.rng.bit_generator.state,
                "rng_views": rng_views.bit_generator.state,
                "torch_rng": torch.get_rng_state(),
            },
            tmp,
        )


def train(
    cfg: TrainConfig, out: str | Path, poses_train: np.ndarray, poses_val: np.ndarray
) -> Path:
    """Train (or resume) a model into directory ``out``; returns ``out``.

    A resumed run is bit-identical to an uninterrupted one: the checkpoint state holds the
    model, the optimizer and every random generator (the sources', the view count's and
    torch's), and log records after the checkpoint (a kill between a logged validation and
    its checkpoint) are dropped on resume.
    """
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    model = build_model(cfg.model_config())
    _check_poses(cfg, model, poses_train, poses_val)
    if cfg.init:
        init_from_checkpoint(model, cfg.init)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    src = _training_source(cfg, poses_train)
    rng_views = np.random.default_rng(cfg.seed)
    progress = _resume(out, model, opt, src, rng_views, cfg.seed)
    sets, mhp_sets, tri = _validation(cfg, poses_val)
    summary = {
        "train_config": asdict(cfg),
        "train_poses": int(len(poses_train)),
        "val_poses": int(len(poses_val)),
        "parameters": model.num_parameters,
    }
    model.train()
    t_start, start_elapsed = time.time(), progress.elapsed
    bar = tqdm(
        total=cfg.steps, initial=progress.step, desc="train", unit="step", dynamic_ncols=True
    )
    while progress.step < cfg.steps:
        V = _num_views(cfg, rng_views)
        loss = _train_step(model, opt, src.batch(cfg.batch_size, V), cfg, progress.step, V)
        progress.step += 1
        if V > 1:  # the running loss follows the multi-view batches
            r = progress.running
            progress.running = loss if r is None else 0.98 * r + 0.02 * loss
        bar.update(1)
        if progress.running is not None:
            bar.set_postfix(loss_mm=f"{progress.running * 1000:.1f}", V=V)
        over_time = cfg.time_limit > 0 and time.time() - t_start > cfg.time_limit
        if progress.step % cfg.val_every == 0 or progress.step == cfg.steps or over_time:
            progress.elapsed = start_elapsed + time.time() - t_start
            record = _validate(model, sets, mhp_sets, tri, progress, out / "log.jsonl", bar)
            save_checkpoint(model, out, {"training": {**summary, "last": record}})
            _save_state(out, model, opt, src, rng_views, progress)
            if over_time:
                log.info("time limit reached at step %d; run again to resume", progress.step)
                break
    bar.close()
    if math.isfinite(progress.running or 0):
        log.info("done: %s", out)
    return out


def _check_poses(cfg: TrainConfig, model: RMPL, poses_train, poses_val) -> None:
    """The pose banks must have the model's joint count (a HALPE-26 model needs HALPE-26)."""
    J = model.config.num_joints
    for name, poses in (("training", poses_train), ("validation", poses_val)):
        if np.shape(poses)[1:] != (J, 3):
            raise InputError(
                cfg.poses, "poses", f"{name} poses of {J} joints, as the model's "
                f"{model.config.skeleton} (rmpl poses --body anny makes HALPE-26)",
                np.shape(poses),
            )  # fmt: skip


def _validate(model, sets, mhp_sets, tri, progress: _Progress, log_file: Path, bar) -> dict:
    """Evaluate, append the record to ``log_file`` and print its KP* errors."""
    metrics = evaluate_batches(model, sets)
    metrics |= {f"mhp_{k}": v for k, v in evaluate_batches(model, mhp_sets).items()}
    record = {
        "step": progress.step,
        "seconds": round(progress.elapsed, 1),
        "train_loss_mm": (progress.running or math.nan) * 1000,
        **metrics,
        **tri,
    }
    with open(log_file, "a") as f:
        f.write(json.dumps(record) + "\n")
    bar.write(
        f"step {progress.step}: "
        + " ".join(f"{k}={v:.1f}" for k, v in metrics.items() if "kpstar" in k)
    )
    return record
