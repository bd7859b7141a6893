"""Train an RMPL lifter on synthetic pairs (resumable: run the same command again).

A config with a ``sequences`` key trains the temporal model (:mod:`rmpl.training.temporal`).

Examples:
  rmpl train configs/default.toml --out runs/default --set poses="../shared/data/cmu_mocap"
  rmpl train configs/temporal.toml --out runs/temporal --set sequences='"seqbank.npz"'
"""

from __future__ import annotations

import argparse
import logging

from rmpl.data.synthetic import SamplerConfig
from rmpl.training.loop import TrainConfig, train

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", help="training config TOML (see configs/)")
    parser.add_argument("--out", required=True, help="run directory (resumes if it exists)")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a config value (TOML syntax), e.g. --set steps=2000 --set model.dim=96",
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import tomllib

    with open(args.config, "rb") as f:
        if "sequences" in tomllib.load(f):
            return _run_temporal(args)
    cfg = TrainConfig.from_toml(args.config, args.overrides)
    if not cfg.poses:
        raise ValueError(
            f"{args.config}: field 'poses' must name a pose bank (.npz) or motion folder"
        )
    bank = load_poses(cfg.poses, on_floor=SamplerConfig(**cfg.sampler).keep_height)
    train_set, val_set = bank.split(cfg.holdout)
    if not len(train_set) or not len(val_set):
        raise ValueError(
            f"{cfg.poses}: holdout subjects {list(cfg.holdout)} must leave both training and "
            f"validation poses; subjects present: {sorted(bank.counts())}"
        )
    log.info(
        "poses: %d train, %d validation (held out: %s)", len(train_set), len(val_set), cfg.holdout
    )
    train(cfg, args.out, train_set.poses, val_set.poses)
    return 0


def _run_temporal(args: argparse.Namespace) -> int:
    from rmpl.training.temporal import TemporalTrainConfig, train_temporal

    cfg = TemporalTrainConfig.from_toml(args.config, args.overrides)
    train_temporal(cfg, args.out)
    return 0


def load_poses(path: str, on_floor: bool = False):
    """A pose bank: an ``.npz`` written by ``rmpl poses``, or a motion-capture folder; with
    ``on_floor`` (``sampler.keep_height``) a sequence bank (``rmpl poses --sequences``) whose
    segments that stand on a floor are levelled to z = 0 (:meth:`SequenceBank.on_floor`)."""
    from pathlib import Path

    from rmpl.data.sequences import FLOOR_CONTACT, SequenceBank
    from rmpl.errors import InputError
    from rmpl.skeleton import BY_COUNT
    from rmpl.synth.motion import load_motion_dir, load_pose_set

    p = Path(path)
    if on_floor:
        if p.is_dir():
            raise InputError(path, "poses", "a sequence bank (rmpl poses --sequences) for "
                             "sampler.keep_height", "a folder")  # fmt: skip
        if not p.is_file():
            raise InputError(path, "poses", "a sequence bank (rmpl poses --sequences) for "
                             "sampler.keep_height", "no such file")  # fmt: skip
        bank = SequenceBank.load(p)
        kept, mask = bank.on_floor(FLOOR_CONTACT[BY_COUNT[bank.poses.shape[1]]])
        log.info("%s: %d of %d segments stand on a floor", path, mask.sum(), len(mask))
        return kept.pose_set()
    if p.is_file():
        return load_pose_set(p)
    if p.is_dir():
        return load_motion_dir(p)
    raise InputError(path, "poses", "a pose bank (.npz) or a motion folder", "no such path")
