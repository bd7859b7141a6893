"""Training a lifter that reads the floor: a tiny real run, fine-tuned from a model
without the floor input (issue 16)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rmpl.inference import Lifter, checkpoint_reads_floor
from rmpl.training.loop import TrainConfig, train

EXAMPLE = Path(__file__).parents[2] / "src/rmpl/examples/walk/ground_truth.npz"


def _config(**kw) -> TrainConfig:
    base = dict(
        preset="tiny", steps=4, batch_size=8, val_every=2, val_size=8, threads=1, lr=1e-3,
        single_view_rate=0.5,
    )  # fmt: skip
    return TrainConfig.from_dict({**base, **kw})


def test_a_floor_model_trains_from_one_without_it(tmp_path):
    p = np.load(EXAMPLE)["points"][:, 0]
    train_poses, val_poses = p[:40], p[40:]
    base = train(_config(), tmp_path / "base", train_poses, val_poses)
    cfg = _config(
        init=str(base),
        model={"floor": True},
        sampler={"keep_height": True, "floor_rate": 0.8},
    )
    run = train(cfg, tmp_path / "floor", train_poses, val_poses)
    assert checkpoint_reads_floor(run) and not checkpoint_reads_floor(base)
    log = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in log] == [2, 4]
    assert all(np.isfinite(r["mpjpe_1v"]) for r in log)
    assert Lifter.from_pretrained(run, backend="torch").reads_floor
