"""Apply the HALPE-26 model's selection rule (configs/halpe26.toml) on held-out data.

    python -m rmpl.benchmarks.halpe26_select BANK.npz CANDIDATE [--base default] [--mhp DIR]
    python -m rmpl.benchmarks.halpe26_select SEQBANK.npz CANDIDATE --temporal [--base temporal]

(a) The parametric synthetic held-out set: CMU subject 03 from the mocap pose bank BANK
(``rmpl poses``, COCO-17), the training validation's detector model and seed (12345, 512
poses per view count, no keypoint removal), COCO-17 input to both models; KP* MPJPE (mm) on
COCO-17 joints at 2-5 views. (b) With ``--mhp DIR``, held-out HALPE-26 renders through
``rmpl.benchmarks.foot_eval``'s estimate for rmpl, both models on the same 2D, KP* at 2-5 views.
The candidate passes when its mean over 2-5 views is at most 2% above the base's on each.

With ``--temporal`` (configs/temporal26.toml's rule): held-out windows of the COCO-17 mocap
sequence bank SEQBANK (subject 03, the training validation's windows: seed 12345, 64 per
view count, 2, 3 and 5 views), COCO-17 input; KP* MPJPE of each temporal model's answer
assembled as its lifter does; the candidate passes at most 2% above the base.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from rmpl.benchmarks._common import run_main
from rmpl.data.synthetic import PairSource, SamplerConfig
from rmpl.inference import Lifter
from rmpl.skeleton import KP_STAR, embed, embed_scores
from rmpl.synth.motion import load_pose_set

VIEWS = (2, 3, 4, 5)
MARGIN = 1.02


def _forward(lifter: Lifter, b) -> np.ndarray:
    """The network on a COCO-17 batch, its input padded to the model's joints: (B, 17, 3)."""
    rays, sc = b.rays, b.scores
    if lifter.num_joints != rays.shape[2]:
        rays = np.nan_to_num(embed(rays, "coco17", lifter.skeleton)).astype(np.float32)
        sc = embed_scores(sc, "coco17", lifter.skeleton).astype(np.float32)
    with torch.no_grad():
        out = lifter.model(torch.from_numpy(rays), torch.from_numpy(sc)).numpy()
    return out[:, :17]


def parametric(bank: Path, lifters: dict[str, Lifter], size: int = 512) -> dict:
    """KP* MPJPE (mm) per model and view count on held-out parametric pairs."""
    poses = load_pose_set(bank)
    _, held = poses.split(["03"])
    src = PairSource(held.poses, SamplerConfig(drop_rate=0.0), seed=12345)
    out: dict[str, dict[int, float]] = {name: {} for name in lifters}
    for v in VIEWS:
        b = src.batch(size, v, train=False)
        for name, lifter in lifters.items():
            e = np.linalg.norm(_forward(lifter, b) - b.target, axis=-1)[:, list(KP_STAR)]
            out[name][v] = float(e.mean() * 1000)
    return out


def renders(root: Path, models: dict[str, str]) -> dict:
    """KP* MPJPE (mm) per model and view count on held-out renders (foot_eval's rmpl)."""
    from rmpl.benchmarks import foot_eval

    d = foot_eval.load_set(root)
    out: dict[str, dict[int, float]] = {}
    for name, model in models.items():
        lifter = Lifter.from_pretrained(model)
        rows = foot_eval.rows_for(d, lifter, list(VIEWS))
        out[name] = {r["views"]: r["kpstar_mm"] for r in rows if r["method"] == "rmpl"}
    return out


def temporal(seqbank: Path, models: dict[str, str], views=(2, 3, 5)) -> dict:
    """KP* MPJPE (mm) of each temporal model's assembled answer on held-out mocap windows."""
    from dataclasses import replace

    from rmpl.data.sequences import SequenceBank
    from rmpl.inference_temporal import PRETRAINED_TEMPORAL, TemporalLifter
    from rmpl.training.temporal import (
        TemporalTrainConfig,
        assembled_windows,
        load_temporal,
        validation_sets,
    )

    _, val = SequenceBank.load(seqbank).split(["03"])
    out: dict[str, dict[int, float]] = {}
    for name, path in models.items():
        model, meta = load_temporal(PRETRAINED_TEMPORAL.get(path, path))
        train = meta.get("training", {}).get("train_config", {})
        cfg = TemporalTrainConfig(noise=train.get("noise", {}), model=train.get("model", {}))
        sets = validation_sets(val, cfg, views=views)
        assemble = TemporalLifter(model, meta, onnx=False).assemble
        skel = model.frame_model.config.skeleton
        out[name] = {}
        for v, b in sets.items():
            if b.rays.shape[3] != model.frame_model.config.num_joints:
                rays = np.nan_to_num(embed(b.rays, "coco17", skel)).astype(np.float32)
                scores = embed_scores(b.scores, "coco17", skel).astype(np.float32)
                b = replace(b, rays=rays, scores=scores)
            points, _ = assembled_windows(model, b, assemble)
            e = np.linalg.norm(points[..., :17, :] - b.target, axis=-1)[..., list(KP_STAR)]
            out[name][v] = float(np.nanmean(e) * 1000)
    return out


def verdict(table: dict, base: str, cand: str, label: str) -> bool:
    views = sorted(table[base])
    mb = np.mean([table[base][v] for v in views])
    mc = np.mean([table[cand][v] for v in views])
    cells = " | ".join(f"{table[base][v]:.1f} / {table[cand][v]:.1f}" for v in views)
    ok = mc <= MARGIN * mb
    rule = "pass" if ok else "fail"
    print(f"| {label} | {cells} | {mb:.1f} / {mc:.1f} | {mc / mb:.3f} | {rule} |")
    return ok


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank", type=Path, help="the mocap pose bank (rmpl poses, COCO-17)")
    ap.add_argument("candidate", help="the HALPE-26 checkpoint")
    ap.add_argument("--base", default="default", help="the model to compare with")
    ap.add_argument("--mhp", type=Path, help="held-out HALPE-26 renders")
    ap.add_argument("--temporal", action="store_true", help="compare temporal models")
    ap.add_argument("--samples", type=int, default=512, help="parametric pairs per view count")
    a = ap.parse_args(argv)
    torch.set_num_threads(2)
    if a.temporal:
        base = "temporal" if a.base == "default" else a.base
        table = temporal(a.bank, {"base": base, "candidate": a.candidate})
        print(
            "| set (base / candidate, KP* mm) | 2 views | 3 views | 5 views | mean | ratio | rule |"
        )
        print("|---|" + "---:|" * 6)
        ok = verdict(table, "base", "candidate", "mocap windows, subject 03")
        print("selected" if ok else "not selected: ships as an opt-in model")
        return 0
    models = {"base": a.base, "candidate": a.candidate}
    lifters = {k: Lifter.from_pretrained(v, backend="torch") for k, v in models.items()}
    head = " | ".join(f"{v} views" for v in VIEWS)
    print(f"| set (base / candidate, KP* mm) | {head} | mean | ratio | rule |")
    print("|---|" + "---:|" * (len(VIEWS) + 3))
    ok = verdict(
        parametric(a.bank, lifters, a.samples), "base", "candidate", "parametric, subject 03"
    )
    if a.mhp:
        ok &= verdict(renders(a.mhp, models), "base", "candidate", f"renders {a.mhp}")
    print("selected" if ok else "not selected: ships as an opt-in model")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
