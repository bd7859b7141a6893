"""Checkpoint folders: ``model.safetensors`` + ``config.json``, per-frame and temporal.

Written by :mod:`rmpl.training` (``rmpl train``), read by the lifters
(:mod:`rmpl.inference`, :mod:`rmpl.inference_temporal`) and the trainers alike.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.model.lifter import RMPL, RMPLConfig, build_model
from rmpl.model.temporal import TemporalConfig, TemporalRMPL

__all__ = [
    "TEMPORAL_FORMAT",
    "checkpoint_meta",
    "checkpoint_tensors",
    "load_checkpoint",
    "load_temporal",
    "write_checkpoint",
]

#: The ``format`` of a temporal checkpoint's ``config.json``.
TEMPORAL_FORMAT = "rmpl-temporal-checkpoint-1"


def write_checkpoint(model: torch.nn.Module, path: str | Path, meta: dict) -> None:
    """A module's weights (``model.safetensors``) and ``meta`` (``config.json``) into
    directory ``path``, each file atomically."""
    from safetensors.torch import save_file

    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    tensors = {k: v.detach().contiguous() for k, v in model.state_dict().items()}
    with atomic_path(path / "model.safetensors") as tmp:
        save_file(tensors, str(tmp))
    with atomic_path(path / "config.json") as tmp:
        tmp.write_text(json.dumps(meta, indent=2))


def load_checkpoint(path: str | Path) -> tuple[RMPL, dict]:
    """Load a checkpoint directory written by :func:`save_checkpoint`.

    Raises:
        InputError: a missing, unreadable or damaged ``config.json`` or ``model.safetensors``,
            or weights that do not fit the config; the message names the file.
    """
    path = Path(path)
    cfg_file, weights = path / "config.json", path / "model.safetensors"
    for f in (cfg_file, weights):
        if not f.is_file():
            raise InputError(
                f, None, "a checkpoint file (a folder with config.json + model.safetensors)",
                "no such file",
            )  # fmt: skip
    meta = checkpoint_meta(cfg_file)
    try:
        model = build_model(RMPLConfig.from_dict(meta["model"]))
    except (TypeError, ValueError, KeyError) as e:
        raise InputError(cfg_file, "model", "an rmpl model configuration", e) from None
    model.load_state_dict(checkpoint_tensors(weights, model))
    return model.eval(), meta


def checkpoint_meta(cfg_file: Path) -> dict:
    try:
        meta = json.loads(cfg_file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(cfg_file, None, "a readable checkpoint config.json", e) from None
    except ValueError as e:
        raise InputError(cfg_file, None, "valid JSON (an rmpl checkpoint)", e) from None
    if not isinstance(meta, dict) or "model" not in meta:
        raise InputError(cfg_file, "model", "a value (an rmpl checkpoint)", "no such key")
    return meta


def checkpoint_tensors(weights: Path, model: RMPL) -> dict:
    from safetensors.torch import load_file

    try:
        tensors = load_file(str(weights))
    except Exception as e:  # noqa: BLE001 - SafetensorError and OSError, by version
        raise InputError(weights, None, "safetensors weights (rmpl train)", e) from None
    want = model.state_dict()
    bad = sorted(
        k for k in set(want) | set(tensors)
        if k not in tensors or k not in want or tensors[k].shape != want[k].shape
    )  # fmt: skip
    if bad:
        raise InputError(weights, None, "the tensors of the model in config.json", bad[:3])
    return tensors


def load_temporal(path: str | Path) -> tuple[TemporalRMPL, dict]:
    """Load a checkpoint written by :func:`save_temporal`.

    Raises:
        InputError: a missing or damaged ``config.json`` / ``model.safetensors``, a per-frame
            checkpoint where a temporal one is expected, or weights that do not fit.
    """
    path = Path(path)
    cfg_file, weights = path / "config.json", path / "model.safetensors"
    for f in (cfg_file, weights):
        if not f.is_file():
            raise InputError(f, None, "a temporal checkpoint file", "no such file")
    meta = checkpoint_meta(cfg_file)
    if meta.get("format") != TEMPORAL_FORMAT:
        raise InputError(cfg_file, "format", TEMPORAL_FORMAT, meta.get("format"))
    try:
        frame = RMPL(RMPLConfig.from_dict(meta["model"]))
        model = TemporalRMPL(frame, TemporalConfig.from_dict(meta["temporal"]))
    except (TypeError, ValueError, KeyError) as e:
        raise InputError(cfg_file, "temporal", "an rmpl temporal configuration", e) from None
    model.load_state_dict(checkpoint_tensors(weights, model))
    return model.eval(), meta
