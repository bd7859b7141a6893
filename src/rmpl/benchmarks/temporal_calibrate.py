"""Fit a temporal checkpoint's per-view-count error radii on held-out synthetic windows.

    python -m rmpl.benchmarks.temporal_calibrate SEQBANK CHECKPOINT [--windows 64] \
        [--mhp DIR ...]

The same windows and rule as training's last validation (CMU subject 03 held out, the
temporal detector model of the checkpoint's recipe, seed 12345, 2, 3 and 5 views), the
answer assembled as the checkpoint's lifter does (``"inference": {"assemble": ...}``):
:func:`rmpl.training.temporal.fit_radius_calibration`. Writes the ``"calibration"`` entry
of ``CHECKPOINT/config.json`` (atomically); the weights are not touched. For checkpoints
trained before the calibration existed; training writes it itself.

With ``--mhp DIR ...`` the radii are fitted on MHP sequences instead (``rmpl generate`` with
``sequence_frames``: renders seen by a real detector; configs/mhp_seq_calib.toml makes a set
of training subjects): ``--windows`` windows of the model's length per view count (2, 3 and
5 views drawn from each sequence's cameras, seed 12345, no augmentation).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch

from rmpl.benchmarks._common import run_main
from rmpl.data.sequences import SequenceBank
from rmpl.inference_temporal import TemporalLifter
from rmpl.io.atomic import atomic_path
from rmpl.training.temporal import (
    TemporalTrainConfig,
    fit_radius_calibration,
    load_temporal,
    validation_sets,
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank")
    ap.add_argument("checkpoint")
    ap.add_argument("--windows", type=int, default=64, help="windows per view count")
    ap.add_argument("--mhp", nargs="+", help="MHP sequence folders to fit on instead")
    a = ap.parse_args(argv)
    torch.set_num_threads(2)
    model, meta = load_temporal(a.checkpoint)
    model.use_onnx()
    train = meta.get("training", {}).get("train_config", {})
    cfg = TemporalTrainConfig(
        noise=train.get("noise", {}), model=train.get("model", {}), val_size=a.windows
    )
    if a.mhp:
        from rmpl.data.mhp import SequenceShardSource

        joints = model.frame_model.config.skeleton
        src = SequenceShardSource(a.mhp, augment=False, seed=12345, joints=joints)
        w = model.config.window
        sets = {v: src.batch(a.windows, w, v, train=False) for v in (2, 3, 5)}
    else:
        _, val = SequenceBank.load(a.bank).split(train.get("holdout", ["03"]))
        sets = validation_sets(val, cfg, views=(2, 3, 5))
    assemble = TemporalLifter(model, meta, onnx=False).assemble
    calibration = fit_radius_calibration(model, sets, assemble=assemble)
    meta["calibration"] = {
        **calibration.to_meta(),
        "fitted_on": "MHP sequences " + ", ".join(a.mhp) if a.mhp else "synthetic windows",
    }
    path = Path(a.checkpoint) / "config.json"
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(meta, indent=2) + "\n")
    print(f"{path}: r50 {calibration.r50}, r90 {calibration.r90}")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
