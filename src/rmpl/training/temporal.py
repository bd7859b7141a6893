"""Training the temporal lifter on synthetic windows (:mod:`rmpl.data.sequences`).

The per-frame model is a shipped or trained checkpoint, frozen by default; only the
space-time transformer learns. The loss is the mean per-joint position error over every
frame of the window (missing frames and unseen joints included: they are what the model is
for) plus a Gaussian negative log-likelihood that trains the uncertainty on the detached
error. A run is resumable: the optimizer, the step and every random state are saved with
each checkpoint, so a resumed run equals an uninterrupted one.
"""

from __future__ import annotations

import json
import logging
import math
import time
import tomllib
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import torch

from rmpl.data.sequences import SequenceBank, SequenceSource, TemporalNoise
from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.model.checkpoint import TEMPORAL_FORMAT as FORMAT
from rmpl.model.checkpoint import load_checkpoint, load_temporal
from rmpl.model.temporal import RADIUS_50, TemporalConfig, TemporalRMPL
from rmpl.skeleton import KP_STAR, skeleton_for

__all__ = [
    "TemporalTrainConfig",
    "fit_radius_calibration",
    "fit_sigma_scale",
    "load_temporal",
    "save_temporal",
    "train_temporal",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TemporalTrainConfig:
    """A temporal training run (TOML: top-level keys, ``[model]``, ``[noise]``).

    Attributes:
        sequences: a sequence bank (.npz, :meth:`SequenceBank.save`) or a motion folder.
        frame_model: the per-frame checkpoint: a shipped name or a directory.
        holdout: subjects never trained on (validation).
        steps, batch_size (windows), lr, weight_decay: optimisation.
        min_views, max_views, single_view_rate: views per batch; single_view_weight: the
            loss weight of one-view batches (their errors are ten times larger).
        nll_weight: weight of the uncertainty's negative log-likelihood.
        val_every, val_size: validation cadence and windows per view count.
        seed, threads, time_limit (seconds, 0 = none; run again to resume).
        model: :class:`TemporalConfig` overrides. noise: :class:`TemporalNoise` overrides.
        mhp_sequences: MHP sequence folders (``rmpl generate`` with ``sequence_frames``):
            renders seen by a real detector over time, mixed into training (their
            ``holdout`` subjects left out). mhp_weight: the share of batches drawn from them.
        floor_rate, floor_noise_m, floor_tilt_deg: for a model that reads the floor
            (``model.floor``): the sequence bank's segments that stand on a floor are levelled
            to it (:meth:`SequenceBank.on_floor`; the others are left out), and this share of
            training windows is given that floor with these errors (sd, metres / degrees).
            Validation windows are given the exact floor. (MHP sequences carry no floor.)
        init: a temporal checkpoint (shipped name or directory) whose temporal stage starts
            this run; the per-frame model is ``frame_model``'s, and inputs the checkpoint
            lacks (the floor's) start at zero, so the run starts at that model.
    """

    sequences: str = ""
    frame_model: str = "default"
    holdout: tuple[str, ...] = ("03",)
    steps: int = 3000
    batch_size: int = 16
    lr: float = 5e-4
    weight_decay: float = 1e-4
    min_views: int = 1
    max_views: int = 5
    single_view_rate: float = 0.05
    single_view_weight: float = 0.1
    nll_weight: float = 0.05
    val_every: int = 500
    val_size: int = 64
    seed: int = 0
    threads: int = 2
    time_limit: float = 0.0
    model: dict = field(default_factory=dict)
    noise: dict = field(default_factory=dict)
    mhp_sequences: tuple[str, ...] = ()
    mhp_weight: float = 0.5
    floor_rate: float = 0.0
    floor_noise_m: float = 0.02
    floor_tilt_deg: float = 1.0
    init: str = ""

    def __post_init__(self) -> None:
        checks = [
            ("steps", self.steps >= 1, ">= 1"),
            ("batch_size", self.batch_size >= 1, ">= 1"),
            ("val_every", self.val_every >= 1, ">= 1"),
            ("val_size", self.val_size >= 1, ">= 1"),
            ("min_views", 1 <= self.min_views <= self.max_views, "in 1..max_views"),
            ("max_views", self.max_views >= 2, ">= 2 (one-view batches: single_view_rate)"),
            ("lr", self.lr > 0, "> 0"),
            ("single_view_rate", 0 <= self.single_view_rate <= 1, "in [0, 1]"),
            ("threads", self.threads >= 1, ">= 1"),
            ("mhp_weight", 0 <= self.mhp_weight <= 1, "in [0, 1]"),
            ("floor_rate", 0 <= self.floor_rate <= 1, "in [0, 1]"),
            ("floor_noise_m", self.floor_noise_m >= 0, ">= 0"),
            ("floor_tilt_deg", self.floor_tilt_deg >= 0, ">= 0"),
        ]
        for name, ok, expected in checks:
            if not ok:
                raise ValueError(f"{name} must be {expected}, got {getattr(self, name)}")

    @classmethod
    def from_toml(
        cls, path: str | Path, overrides: list[str] | dict | None = None
    ) -> TemporalTrainConfig:
        """Read a TOML file; ``overrides``: ``key=value`` strings (TOML values) or a dict."""
        from rmpl.training.loop import apply_overrides

        with open(path, "rb") as f:
            d = tomllib.load(f)
        if isinstance(overrides, dict):
            d |= overrides
        else:
            d = apply_overrides(d, overrides)
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise InputError(path, ", ".join(sorted(unknown)), f"one of {sorted(known)}")
        for key in ("holdout", "mhp_sequences"):
            if key in d:
                d[key] = (d[key],) if isinstance(d[key], str) else tuple(d[key])
        return cls(**d)

    def model_config(self) -> TemporalConfig:
        return TemporalConfig.from_dict(self.model)

    def noise_config(self) -> TemporalNoise:
        return TemporalNoise.from_dict(self.noise)

    @property
    def reads_floor(self) -> bool:
        return bool(self.model.get("floor", False))

    def source_floor(self, train: bool = True) -> tuple[float, float, float]:
        """``SequenceSource(floor=)``: training windows as configured, validation ones all
        given the exact floor (when the model reads it)."""
        if not self.reads_floor:
            return (0.0, 0.0, 0.0)
        return (self.floor_rate, self.floor_noise_m, self.floor_tilt_deg) if train else (1, 0, 0)


def _load_bank(cfg: TemporalTrainConfig) -> tuple[SequenceBank, SequenceBank]:
    path = Path(cfg.sequences)
    if path.is_dir():
        bank = SequenceBank.from_motion_dir(path)
    elif path.is_file():
        bank = SequenceBank.load(path)
    else:
        raise InputError(cfg.sequences or "(empty)", "sequences", "a sequence bank or a folder")
    if cfg.reads_floor:
        from rmpl.data.sequences import FLOOR_CONTACT
        from rmpl.skeleton import BY_COUNT

        bank, kept = bank.on_floor(FLOOR_CONTACT[BY_COUNT[bank.poses.shape[1]]])
        log.info("%s: %d of %d segments stand on a floor", path, kept.sum(), len(kept))
    train, val = bank.split(cfg.holdout)
    if len(train) == 0 or len(val) == 0:
        raise InputError(path, "holdout", "subjects that leave both training and validation data")
    return train, val


def build_temporal(cfg: TemporalTrainConfig) -> TemporalRMPL:
    """A new temporal model around the per-frame checkpoint ``cfg.frame_model``."""
    from rmpl.models import PRETRAINED

    frame, _ = load_checkpoint(PRETRAINED.get(cfg.frame_model, Path(cfg.frame_model)))
    model = TemporalRMPL(frame, cfg.model_config())
    if cfg.init:
        _init_from(model, cfg.init)
    return model


def _init_from(model: TemporalRMPL, name_or_path: str) -> None:
    """Copy the temporal stage of checkpoint ``name_or_path`` into ``model`` (see
    ``TemporalTrainConfig.init``); every tensor but the new floor input must fit."""
    from rmpl.models import PRETRAINED_TEMPORAL

    path = Path(PRETRAINED_TEMPORAL.get(name_or_path, name_or_path))
    source, _ = load_temporal(path)
    stage = {k: v for k, v in source.state_dict().items() if not k.startswith("frame_model.")}
    try:
        missing, unexpected = model.load_state_dict(stage, strict=False)
    except RuntimeError as e:  # a tensor of another shape
        raise InputError(path, "init", "a temporal checkpoint of the same architecture",
                         str(e).splitlines()[-1].strip()) from None  # fmt: skip
    missing = [k for k in missing if not k.startswith(("frame_model.", "floor_in."))]
    if missing or unexpected:
        raise InputError(
            path, "init", "a temporal checkpoint of the same architecture",
            f"missing {missing}, unexpected {unexpected}",
        )  # fmt: skip


def save_temporal(model: TemporalRMPL, path: str | Path, extra: dict | None = None) -> None:
    """Write ``model.safetensors`` (per-frame and temporal weights) and ``config.json``."""
    from rmpl.model.checkpoint import write_checkpoint

    meta = {
        "format": FORMAT,
        "model": model.frame_model.config.to_dict(),
        "temporal": model.config.to_dict(),
        "skeleton": model.frame_model.config.skeleton,
        "joints": list(skeleton_for(model.frame_model.config.skeleton).joints),
        "units": "metres",
        **(extra or {}),
    }
    write_checkpoint(model, path, meta)


def _tensors(b) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    return tuple(torch.from_numpy(a) for a in (b.rays, b.scores, b.times, b.target))


def _floor(b) -> torch.Tensor | None:
    """The batch's floor rows (B, 4), or None (MHP sequences and floorless sources)."""
    floor = getattr(b, "floor", None)
    return None if floor is None else torch.from_numpy(floor)


def loss_terms(model: TemporalRMPL, b) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(position loss in metres, uncertainty NLL, per-joint errors (B, T, J)) on a batch."""
    rays, scores, times, target = _tensors(b)
    points, sigma = model(rays, scores, times, _floor(b))
    seen = (scores > 0).flatten(1).any(1)  # (B,) windows with nothing seen give NaN: skipped
    target = target[seen]
    known = torch.isfinite(target).all(-1)  # COCO-17 sets read as HALPE-26 lack 9 targets
    err = (points[seen] - torch.nan_to_num(target)).norm(dim=-1)  # (B', T, J)
    s = sigma[seen].clamp_min(1e-3)
    nll = 3 * s.log() + err.detach() ** 2 / (2 * s**2)
    if bool(known.all()):
        return err.mean(), nll.mean(), err
    n = known.sum().clamp(min=1)
    return (err * known).sum() / n, (nll * known).sum() / n, err.masked_fill(~known, float("nan"))


def validation_sets(val: SequenceBank, cfg: TemporalTrainConfig, views=(1, 2, 3, 5)) -> dict:
    """Fixed windows of held-out motion per number of views (seeded, no keypoint removal)."""
    src = SequenceSource(
        val, temporal=cfg.noise_config(), seed=12345, floor=cfg.source_floor(train=False)
    )
    T = cfg.model_config().window
    return {v: src.batch(cfg.val_size, T, v, train=False) for v in views}


@torch.no_grad()
def evaluate_windows(model: TemporalRMPL, sets: dict) -> dict[str, float]:
    """Per view count: KP* MPJPE (mm) of the temporal model and of the per-frame model alone,
    all joints and joints seen in fewer than 2 views; the uncertainty's 50%/90% coverage."""
    model.eval()
    out = {}
    for v, b in sets.items():
        rays, scores, times, target = _tensors(b)
        points, sigma = model(rays, scores, times, _floor(b))
        frame = model.encode_frames(rays, scores, _floor(b))[0]
        e = (points - target).norm(dim=-1).numpy()[..., list(KP_STAR)]
        ef = (frame - target).norm(dim=-1).numpy()[..., list(KP_STAR)]
        seen = (b.scores > 0).sum(2)[..., list(KP_STAR)]
        frame_ok = (b.scores > 0).any((2, 3))[..., None].repeat(len(KP_STAR), -1)
        hard = (seen < 2) & frame_ok
        r = sigma.numpy()[..., list(KP_STAR)]
        out[f"kpstar_{v}v"] = float(np.nanmean(e) * 1000)
        out[f"frame_kpstar_{v}v"] = float(np.mean(ef[frame_ok]) * 1000)
        out[f"temporal_seenframes_{v}v"] = float(np.mean(e[frame_ok]) * 1000)
        if hard.any():
            out[f"hard_{v}v"] = float(np.mean(e[hard]) * 1000)
            out[f"frame_hard_{v}v"] = float(np.mean(ef[hard]) * 1000)
        out[f"cover50_{v}v"] = float(np.mean(e < RADIUS_50 * r))
    model.train()
    return out


@torch.no_grad()
def fit_sigma_scale(model: TemporalRMPL, sets: dict) -> float:
    """The factor that makes half of the held-out errors fall inside the 50% radius."""
    model.eval()
    ratios = []
    for b in sets.values():
        rays, scores, times, target = _tensors(b)
        points, sigma = model(rays, scores, times, _floor(b))
        raw = sigma / model.config.sigma_scale
        ratios.append(((points - target).norm(dim=-1) / raw).flatten().numpy())
    r = np.concatenate(ratios)
    return float(np.median(r[np.isfinite(r)]) / RADIUS_50)


def radius_quantiles(
    errors: np.ndarray, sigma: np.ndarray, num_views: np.ndarray, max_views: int = 5,
    min_count: int = 200,
):  # fmt: skip
    """Per number of views k = 0..max_views (the last: k or more), the 50% and 90% quantiles
    of ``errors / sigma`` (any matching shapes; non-finite entries are left out). A group
    with fewer than ``min_count`` joints takes the pooled quantiles.

    Returns:
        a :class:`rmpl.inference_temporal.RadiusCalibration`.

    >>> e = np.array([1.0, 2, 3, 4, 10, 20, 30, 40]); s = np.ones(8)
    >>> c = radius_quantiles(e, s, np.array([0, 0, 0, 0, 2, 2, 2, 2]), 2, min_count=4)
    >>> c.r50, c.r90
    ((2.5, 7.0, 25.0), (3.7, 33.0, 37.0))
    """
    from rmpl.inference_temporal import RadiusCalibration

    ratio = np.asarray(errors, float) / np.asarray(sigma, float)
    k = np.clip(np.asarray(num_views), 0, max_views)
    ok = np.isfinite(ratio) & (np.asarray(sigma) > 0)
    if ok.sum() < min_count:
        raise ValueError(f"{int(ok.sum())} finite errors: too few to calibrate (< {min_count})")
    pooled = np.quantile(ratio[ok], [0.5, 0.9])
    r50, r90 = [], []
    for v in range(max_views + 1):
        group = ratio[ok & (k == v)]
        q = np.quantile(group, [0.5, 0.9]) if len(group) >= min_count else pooled
        r50.append(round(float(q[0]), 4))
        r90.append(round(float(max(q[1], q[0])), 4))
    return RadiusCalibration(tuple(r50), tuple(r90))


@torch.no_grad()
def assembled_windows(model: TemporalRMPL, b, assemble: str = "network"):
    """The model's answer on a batch of windows as a lifter assembles it
    (:data:`rmpl.inference_temporal.ASSEMBLE`): points (B, T, J, 3), sigma (B, T, J) numpy."""
    from rmpl.inference_temporal import assemble_track

    rays, scores, times, _ = _tensors(b)
    floor = _floor(b)
    encoded = model.encode_frames(rays, scores, floor)  # model(...), keeping the frame answer
    points, sigma = (x.numpy() for x in model.forward_encoded(*encoded, times, floor))
    if assemble == "filtered":
        frame = encoded[0].numpy()
        views = (b.scores > 0).sum(2)
        points = np.stack([assemble_track(points[i], frame[i], views[i], b.times[i])
                           for i in range(len(points))])  # fmt: skip
    return points, sigma


@torch.no_grad()
def fit_radius_calibration(
    model: TemporalRMPL, sets: dict, min_views: int = 2, assemble: str = "network"
):
    """:func:`radius_quantiles` of the model, its answer assembled as ``assemble``, on
    held-out windows (``sets``: view count -> batch), from the sets with at least
    ``min_views`` views: one-view rigs have their own error scale and are not what the
    temporal model serves."""
    model.eval()
    err, sig, views = [], [], []
    for v, b in sets.items():
        if v < min_views:
            continue
        points, sigma = assembled_windows(model, b, assemble)
        err.append(np.linalg.norm(points - b.target, axis=-1).flatten())
        sig.append(sigma.flatten())
        views.append((b.scores > 0).sum(2).flatten())
    return radius_quantiles(np.concatenate(err), np.concatenate(sig), np.concatenate(views))


def _lr_at(step: int, cfg: TemporalTrainConfig) -> float:
    warmup = min(200, cfg.steps // 20)
    f = min(1.0, (step + 1) / max(warmup, 1))
    return cfg.lr * f * 0.5 * (1 + math.cos(math.pi * min(step / max(cfg.steps, 1), 1.0)))


def _views(rng: np.random.Generator, cfg: TemporalTrainConfig) -> int:
    if cfg.min_views == 1 and rng.random() < cfg.single_view_rate:
        return 1
    return int(rng.integers(max(cfg.min_views, 2), cfg.max_views + 1))


class _Run:
    """The mutable state of a run: model, optimizer, sources, step; saved and restored whole."""

    def __init__(self, cfg: TemporalTrainConfig, out: Path, train_bank: SequenceBank) -> None:
        self.cfg, self.out = cfg, out
        torch.manual_seed(cfg.seed)
        self.model = build_temporal(cfg)
        if self.model.config.frozen_encoder:
            self.model.use_onnx(cfg.threads)
        params = [p for p in self.model.parameters() if p.requires_grad]
        self.opt = torch.optim.AdamW(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
        self.src = SequenceSource(
            train_bank, temporal=cfg.noise_config(), seed=cfg.seed, floor=cfg.source_floor()
        )
        self.rng_views = np.random.default_rng(cfg.seed + 1)
        # MHP sequences have their own generators, drawn from only when they are used, so
        # runs without them stay bit-identical to those made before they existed.
        self.mhp = self.rng_mix = None
        if cfg.mhp_sequences:
            from rmpl.data.mhp import SequenceShardSource

            self.mhp = SequenceShardSource(
                list(cfg.mhp_sequences),
                exclude_subjects=cfg.holdout,
                seed=cfg.seed + 2,
                joints=self.model.frame_model.config.skeleton,
            )
            if self.mhp.num_frames < self.model.config.window:
                raise InputError(
                    cfg.mhp_sequences[0], "mhp_sequences",
                    f"sequences of at least the model's window, {self.model.config.window} "
                    "frames", f"{self.mhp.num_frames} frames",
                )  # fmt: skip
            self.rng_mix = np.random.default_rng(cfg.seed + 3)
        self.step, self.elapsed, self.running = 0, 0.0, None

    @property
    def state_file(self) -> Path:
        return self.out / "state.pt"

    def resume(self) -> bool:
        if not self.state_file.exists():
            return False
        s = torch.load(self.state_file, weights_only=False)
        self.model.load_state_dict(s["model"])
        self.opt.load_state_dict(s["optimizer"])
        self.step, self.elapsed, self.running = s["step"], s["elapsed"], s["running"]
        self.src.rng.bit_generator.state = s["rng_source"]
        self.rng_views.bit_generator.state = s["rng_views"]
        if self.mhp is not None:
            self.mhp.rng.bit_generator.state = s["rng_mhp"]
            self.rng_mix.bit_generator.state = s["rng_mix"]
        torch.set_rng_state(s["rng_torch"])
        return True

    def save_state(self) -> None:
        state = {
            "model": self.model.state_dict(),
            "optimizer": self.opt.state_dict(),
            "step": self.step,
            "elapsed": self.elapsed,
            "running": self.running,
            "rng_source": self.src.rng.bit_generator.state,
            "rng_views": self.rng_views.bit_generator.state,
            "rng_torch": torch.get_rng_state(),
        }
        if self.mhp is not None:
            state["rng_mhp"] = self.mhp.rng.bit_generator.state
            state["rng_mix"] = self.rng_mix.bit_generator.state
        with atomic_path(self.state_file) as tmp:
            torch.save(state, tmp)

    def train_step(self) -> float:
        cfg = self.cfg
        V = _views(self.rng_views, cfg)
        W = self.model.config.window
        if self.mhp is not None and self.rng_mix.random() < cfg.mhp_weight:
            b = self.mhp.batch(cfg.batch_size, W, min(V, self.mhp.num_views))
        else:
            b = self.src.batch(cfg.batch_size, W, V)
        for g in self.opt.param_groups:
            g["lr"] = _lr_at(self.step, cfg)
        loss, nll, _ = loss_terms(self.model, b)
        total = (loss + cfg.nll_weight * nll) * (cfg.single_view_weight if V == 1 else 1.0)
        if not torch.isfinite(total):
            raise RuntimeError(f"non-finite loss at step {self.step}; stopping without saving")
        self.opt.zero_grad(set_to_none=True)
        total.backward()
        torch.nn.utils.clip_grad_norm_(self.model.parameters(), 1.0)
        self.opt.step()
        self.step += 1
        value = loss.item()
        if V > 1:  # the running loss follows the multi-view batches
            self.running = value if self.running is None else 0.98 * self.running + 0.02 * value
        return value


def _write_log(out: Path, record: dict) -> None:
    """Append ``record`` to log.jsonl, first dropping records of steps at or after it (left by
    a run killed between its log line and its checkpoint)."""
    path = out / "log.jsonl"
    lines = path.read_text().splitlines() if path.exists() else []
    keep = [ln for ln in lines if ln.strip() and json.loads(ln)["step"] < record["step"]]
    with atomic_path(path) as tmp:
        tmp.write_text("".join(ln + "\n" for ln in keep + [json.dumps(record)]))


def train_temporal(cfg: TemporalTrainConfig, out: str | Path) -> Path:
    """Train (or resume) a temporal model into directory ``out``; returns ``out``."""
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.threads)
    train_bank, val_bank = _load_bank(cfg)
    run = _Run(cfg, out, train_bank)
    if run.resume():
        log.info("resuming %s at step %d", out, run.step)
    sets = validation_sets(val_bank, cfg)
    summary = {
        "train_config": asdict(cfg),
        "train_segments": len(train_bank),
        "val_segments": len(val_bank),
        "parameters": run.model.num_parameters,
    }
    run.model.train()
    t_start, start_elapsed = time.time(), run.elapsed
    bar = tqdm(total=cfg.steps, initial=run.step, desc="train", unit="step", dynamic_ncols=True)
    while run.step < cfg.steps:
        run.train_step()
        run.elapsed = start_elapsed + time.time() - t_start
        bar.update(1)
        if run.running is not None:
            bar.set_postfix(loss_mm=f"{run.running * 1000:.1f}")
        over_time = cfg.time_limit > 0 and time.time() - t_start > cfg.time_limit
        if run.step % cfg.val_every == 0 or run.step == cfg.steps or over_time:
            _checkpoint(run, sets, summary, bar)
            if over_time:
                log.info("time limit reached at step %d; run again to resume", run.step)
                break
    bar.close()
    return out


def _checkpoint(run: _Run, sets: dict, summary: dict, bar) -> None:
    """Validate, calibrate the uncertainty, write the model, the log line and the state."""
    model = run.model  # trains with sigma_scale = 1; the saved model carries the calibration
    scale = fit_sigma_scale(model, sets)
    model.config = model.config.with_(sigma_scale=scale)
    calibration = fit_radius_calibration(model, sets)
    metrics = evaluate_windows(model, sets)
    record = {
        "step": run.step,
        "seconds": round(run.elapsed, 1),
        "train_loss_mm": (run.running or math.nan) * 1000,
        "sigma_scale": scale,
        **metrics,
    }
    bar.write(
        f"step {run.step}: "
        + " ".join(
            f"{k}={v:.1f}"
            for k, v in metrics.items()
            if k.startswith(("kpstar", "frame_kp", "hard"))
        )
    )
    extra = {"training": {**summary, "last": record}, "calibration": calibration.to_meta()}
    save_temporal(model, run.out, extra)
    model.config = model.config.with_(sigma_scale=1.0)
    _write_log(run.out, record)
    run.save_state()
