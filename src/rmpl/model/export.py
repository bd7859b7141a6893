"""Run the lifter through onnxruntime: the same network, about twice as fast on CPU."""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np
import torch

from rmpl.model.lifter import RMPL

__all__ = ["CACHE_ENV", "OnnxLifter", "export_key", "export_onnx"]


def export_onnx(
    model: torch.nn.Module,
    path: str | Path,
    output_names: tuple[str, ...] = ("joints",),
    num_joints: int | None = None,
    floor: bool | None = None,
) -> Path:
    """Export ``model(rays, scores)`` to ONNX with dynamic batch and view axes (outputs
    ``output_names``, each with a dynamic batch axis). A model that reads the floor
    (``config.floor``, or ``floor=True`` for a wrapper taking it third) takes a third
    input, ``floor`` (B, 4)."""
    model = model.eval()
    J = num_joints or model.config.num_joints
    rays = torch.randn(2, 3, J, 6)
    rays[..., 3:] /= rays[..., 3:].norm(dim=-1, keepdim=True)
    scores = torch.rand(2, 3, J)
    args, names, axes = (rays, scores), ["rays", "scores"], {"rays": {0: "B", 1: "V"}}
    axes |= {"scores": {0: "B", 1: "V"}}
    if floor is None:
        floor = bool(getattr(getattr(model, "config", None), "floor", False))
    if floor:
        model = _WithFloor(model) if isinstance(model, RMPL) else model
        args, names = (*args, torch.tensor([[0.0, 0, 1, 0], [np.nan] * 4])), [*names, "floor"]
        axes |= {"floor": {0: "B"}}
    with warnings.catch_warnings():  # tracer notes on shape checks: harmless, not for users
        warnings.simplefilter("ignore")
        torch.onnx.export(
            model,
            args,
            str(path),
            input_names=names,
            output_names=list(output_names),
            dynamic_axes=axes | {n: {0: "B"} for n in output_names},
            opset_version=17,
            dynamo=False,
        )
    return Path(path)


class _WithFloor(torch.nn.Module):
    """``model(rays, scores, floor=floor)`` as a module with positional inputs (for export)."""

    def __init__(self, model: RMPL) -> None:
        super().__init__()
        self.model, self.config = model, model.config

    def forward(self, rays: torch.Tensor, scores: torch.Tensor, floor: torch.Tensor):
        return self.model(rays, scores, floor=floor)


#: Where exported networks are kept (``$RMPL_ONNX_CACHE``, else ``~/.cache/rmpl/onnx``;
#: ``RMPL_ONNX_CACHE=off`` exports every time). A file's name is a hash of everything the
#: export depends on, so a changed model or rmpl version never reads a stale one.
CACHE_ENV = "RMPL_ONNX_CACHE"


def _cache_dir() -> Path | None:
    import os

    where = os.environ.get(CACHE_ENV)
    if where == "off":
        return None
    return Path(where) if where else Path.home() / ".cache" / "rmpl" / "onnx"


def export_key(model: torch.nn.Module, **export) -> str:
    """A hash of what :func:`export_onnx` of ``model`` depends on: the weights and buffers,
    the config, the module's class, the export options, torch's version and the source of
    ``rmpl.model`` and ``rmpl.skeleton``."""
    import dataclasses
    import hashlib

    import rmpl.model
    import rmpl.skeleton

    h = hashlib.sha256()
    h.update(f"{torch.__version__}|{type(model).__module__}.{type(model).__qualname__}".encode())
    h.update(repr(sorted(export.items())).encode())
    config = getattr(model, "config", None)
    if dataclasses.is_dataclass(config):
        h.update(repr(dataclasses.asdict(config)).encode())
    sources = sorted(Path(rmpl.model.__file__).parent.glob("*.py"))
    for src in [*sources, Path(rmpl.skeleton.__file__)]:
        h.update(src.read_bytes())
    for name, tensor in model.state_dict().items():
        h.update(f"{name}|{tuple(tensor.shape)}|{tensor.dtype}".encode())
        h.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()[:32]


def _exported(model: torch.nn.Module, folder: str, **export) -> Path:
    """The ONNX file of ``model``: from the cache when it holds this export, else exported
    (into the cache when it is writable, else into ``folder``)."""
    import logging

    from rmpl.io.atomic import atomic_path

    cache = _cache_dir()
    if cache is not None:
        path = cache / f"{export_key(model, **export)}.onnx"
        if path.is_file():
            return path
        try:
            with atomic_path(path) as tmp:
                export_onnx(model, tmp, **export)
            return path
        except OSError as e:  # a read-only home: export where the session can read it
            logging.getLogger(__name__).debug("ONNX cache %s not writable: %s", cache, e)
    return export_onnx(model, Path(folder) / "model.onnx", **export)


def _session(model: torch.nn.Module, threads: int, **export):
    """An onnxruntime session on ``model`` exported by :func:`export_onnx` (kept in the
    cache, :data:`CACHE_ENV`, for the next run)."""
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads
    with tempfile.TemporaryDirectory() as d:
        path = _exported(model, d, **export)
        try:
            return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
        except Exception:  # a damaged cache file: export again, beside the session
            if Path(d) in path.parents:
                raise
            path.unlink(missing_ok=True)
            path = export_onnx(model, Path(d) / "model.onnx", **export)
            return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])


class OnnxLifter:
    """The same network run by onnxruntime: ``__call__(rays, scores[, floor]) -> joints``
    (numpy; ``floor`` (B, 4), NaN rows = unknown, for a model that reads the floor)."""

    def __init__(self, model: RMPL, threads: int = 2) -> None:
        self.floor = bool(getattr(model.config, "floor", False))
        self.session = _session(model, threads)

    def __call__(
        self, rays: np.ndarray, scores: np.ndarray, floor: np.ndarray | None = None
    ) -> np.ndarray:
        feed = {"rays": rays, "scores": scores}
        if self.floor:
            if floor is None:
                floor = np.full((len(rays), 4), np.nan, np.float32)
            feed["floor"] = np.asarray(floor, np.float32)
        return self.session.run(None, feed)[0]


class _EncodeOutputs(torch.nn.Module):
    """``RMPL.encode`` as a module with tensor outputs (for export)."""

    def __init__(self, model: RMPL) -> None:
        super().__init__()
        self.model = model

    def forward(self, rays: torch.Tensor, scores: torch.Tensor, floor: torch.Tensor | None = None):
        enc = self.model.encode(rays, scores, floor=floor)
        answer = enc.base + self.model.head(enc.tokens)
        return answer, enc.base, enc.tokens, enc.valid.to(rays.dtype), enc.views.to(rays.dtype)


class OnnxEncoder:
    """:meth:`RMPL.encode` (and the answer) run by onnxruntime, for a frozen per-frame model.

    ``__call__(rays (B, V, J, 6), scores (B, V, J)[, floor (B, 4)])`` returns numpy arrays
    answer (B, J, 3), base (B, J, 3), tokens (B, J, D), valid (B, J) and views (B, J) as
    floats; ``floor`` (NaN rows = unknown) is read by a model that reads the floor.
    """

    def __init__(self, model: RMPL, threads: int = 2) -> None:
        names = ("answer", "base", "tokens", "valid", "views")
        wrapper = _EncodeOutputs(model.eval())
        self.floor = bool(model.config.floor)
        self.session = _session(
            wrapper,
            threads,
            output_names=names,
            num_joints=model.config.num_joints,
            floor=self.floor,
        )

    def __call__(
        self, rays: np.ndarray, scores: np.ndarray, floor: np.ndarray | None = None
    ) -> tuple[np.ndarray, ...]:
        feed = {"rays": rays, "scores": scores}
        if self.floor:
            if floor is None:
                floor = np.full((len(rays), 4), np.nan, np.float32)
            feed["floor"] = np.asarray(floor, np.float32)
        return tuple(self.session.run(None, feed))
