"""Run the lifter through onnxruntime: the same network, about twice as fast on CPU."""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np
import torch

from rmpl.model.lifter import RMPL

__all__ = ["export_onnx", "OnnxLifter"]


def export_onnx(model: RMPL, path: str | Path) -> Path:
    """Export the model to ONNX with dynamic batch and view axes."""
    model = model.eval()
    rays = torch.randn(2, 3, model.config.num_joints, 6)
    rays[..., 3:] /= rays[..., 3:].norm(dim=-1, keepdim=True)
    scores = torch.rand(2, 3, model.config.num_joints)
    with warnings.catch_warnings():  # tracer notes on shape checks: harmless, not for users
        warnings.simplefilter("ignore")
        _export(model, rays, scores, path)
    return Path(path)


def _export(model: RMPL, rays: torch.Tensor, scores: torch.Tensor, path) -> None:
    torch.onnx.export(
        model,
        (rays, scores),
        str(path),
        input_names=["rays", "scores"],
        output_names=["joints"],
        dynamic_axes={"rays": {0: "B", 1: "V"}, "scores": {0: "B", 1: "V"}, "joints": {0: "B"}},
        opset_version=17,
        dynamo=False,
    )


class OnnxLifter:
    """The same network run by onnxruntime: ``__call__(rays, scores) -> joints`` (numpy)."""

    def __init__(self, model: RMPL, threads: int = 2) -> None:
        import onnxruntime as ort

        with tempfile.TemporaryDirectory() as d:
            path = export_onnx(model, Path(d) / "rmpl.onnx")
            opts = ort.SessionOptions()
            opts.intra_op_num_threads = threads
            self.session = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])

    def __call__(self, rays: np.ndarray, scores: np.ndarray) -> np.ndarray:
        return self.session.run(None, {"rays": rays, "scores": scores})[0]


class _EncodeOutputs(torch.nn.Module):
    """``RMPL.encode`` as a module with tensor outputs (for export)."""

    def __init__(self, model: RMPL) -> None:
        super().__init__()
        self.model = model

    def forward(self, rays: torch.Tensor, scores: torch.Tensor):
        enc = self.model.encode(rays, scores)
        answer = enc.base + self.model.head(enc.tokens)
        return answer, enc.base, enc.tokens, enc.valid.to(rays.dtype), enc.views.to(rays.dtype)


class OnnxEncoder:
    """:meth:`RMPL.encode` (and the answer) run by onnxruntime, for a frozen per-frame model.

    ``__call__(rays (B, V, J, 6), scores (B, V, J))`` returns numpy arrays answer (B, J, 3),
    base (B, J, 3), tokens (B, J, D), valid (B, J) and views (B, J) as floats.
    """

    def __init__(self, model: RMPL, threads: int = 2) -> None:
        import onnxruntime as ort

        wrapper = _EncodeOutputs(model.eval())
        rays = torch.randn(2, 3, model.config.num_joints, 6)
        rays[..., 3:] /= rays[..., 3:].norm(dim=-1, keepdim=True)
        scores = torch.rand(2, 3, model.config.num_joints)
        names = ["answer", "base", "tokens", "valid", "views"]
        with tempfile.TemporaryDirectory() as d, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            path = Path(d) / "encode.onnx"
            torch.onnx.export(
                wrapper,
                (rays, scores),
                str(path),
                input_names=["rays", "scores"],
                output_names=names,
                dynamic_axes={"rays": {0: "B", 1: "V"}, "scores": {0: "B", 1: "V"}}
                | {n: {0: "B"} for n in names},
                opset_version=17,
                dynamo=False,
            )
            opts = ort.SessionOptions()
            opts.intra_op_num_threads = threads
            self.session = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])

    def __call__(self, rays: np.ndarray, scores: np.ndarray) -> tuple[np.ndarray, ...]:
        return tuple(self.session.run(None, {"rays": rays, "scores": scores}))
