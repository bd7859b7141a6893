"""Speed and memory of the lifter presets and of triangulation, on this machine.

Every figure is frames per second, where a frame is one person seen by V views
(thesis table 6.7). Models run untrained weights: speed does not depend on training.
"""

from __future__ import annotations

import resource
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.geometry.triangulate import triangulate, triangulate_robust
from rmpl.model.lifter import PRESETS, RMPL

__all__ = ["export_onnx", "OnnxLifter", "run_bench", "synthetic_inputs"]


def synthetic_inputs(batch: int, views: int, seed: int = 0):
    """Random rays/scores plus matching pixels and a rig, for timing."""
    rng = np.random.default_rng(seed)
    ang = np.linspace(0, 2 * np.pi, views, endpoint=False)
    K = np.array([[1000.0, 0, 500], [0, 1000, 400], [0, 0, 1]])
    cams = tuple(
        Camera(K, *look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 2.0]), np.array([0, 0, 1.0])),
               size=(1000, 800), name=str(i))  # fmt: skip
        for i, a in enumerate(ang)
    )
    rig = Rig(cams)
    X = rng.uniform(-0.4, 0.4, (batch, 17, 3)) + [0, 0, 1]
    kp = rig.project(X) + rng.normal(0, 2, (batch, views, 17, 2))
    scores = rng.uniform(0.3, 1.0, (batch, views, 17))
    from rmpl.geometry.rays import rays_from_keypoints

    rays = rays_from_keypoints(kp, rig).astype(np.float32)
    return rays, scores.astype(np.float32), kp, rig


def export_onnx(model: RMPL, path: str | Path) -> Path:
    """Export the model to ONNX with dynamic batch and view axes."""
    model = model.eval()
    rays = torch.randn(2, 3, model.config.num_joints, 6)
    rays[..., 3:] /= rays[..., 3:].norm(dim=-1, keepdim=True)
    scores = torch.rand(2, 3, model.config.num_joints)
    torch.onnx.export(
        model, (rays, scores), str(path), input_names=["rays", "scores"], output_names=["joints"],
        dynamic_axes={"rays": {0: "B", 1: "V"}, "scores": {0: "B", 1: "V"}, "joints": {0: "B"}},
        opset_version=17, dynamo=False,
    )  # fmt: skip
    return Path(path)


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


def _rate(fn: Callable[[], object], frames: int, min_time: float = 0.5) -> float:
    fn()  # warm-up
    n, start = 0, time.perf_counter()
    while True:
        fn()
        n += 1
        elapsed = time.perf_counter() - start
        if elapsed >= min_time and n >= 3:
            return frames * n / elapsed


def run_bench(
    presets=("default", "paper"),
    views=(1, 2, 3, 4, 5, 6, 7, 8),
    batches=(1, 8, 64, 512),
    backends=("torch", "onnx"),
    min_time: float = 0.5,
    progress: bool = True,
) -> list[dict]:
    """Time each (method, backend, views, batch); returns one row per measurement."""
    from tqdm import tqdm

    from rmpl.inference import PRETRAINED

    torch.set_num_threads(2)
    models = {}
    for name in presets:
        if name == "default" and (PRETRAINED["default"] / "config.json").is_file():
            from rmpl.train import load_checkpoint

            models[name] = load_checkpoint(PRETRAINED["default"])[0]
        else:
            models[name] = RMPL(PRESETS[name if name in PRESETS else "small"]).eval()
    runners = {}
    for name, model in models.items():
        if "torch" in backends:
            runners[(name, "torch")] = lambda r, s, m=model: m(torch.from_numpy(r), torch.from_numpy(s))
        if "onnx" in backends:
            runners[(name, "onnx")] = OnnxLifter(model)
    rows = []
    jobs = [(v, b) for v in views for b in batches]
    for v, b in tqdm(jobs, desc="bench", disable=not progress):
        rays, scores, kp, rig = synthetic_inputs(b, v)
        with torch.no_grad():
            for (name, backend), fn in runners.items():
                rate = _rate(lambda fn=fn: fn(rays, scores), b, min_time)
                rows.append({"method": f"rmpl-{name}", "backend": backend, "views": v,
                             "batch": b, "fps": rate})  # fmt: skip
        if v >= 2:
            rows.append({"method": "triangulate", "backend": "numpy", "views": v, "batch": b,
                         "fps": _rate(lambda: triangulate(kp, scores, rig), b, min_time)})  # fmt: skip
            rows.append({"method": "triangulate_robust", "backend": "numpy", "views": v, "batch": b,
                         "fps": _rate(lambda: triangulate_robust(kp, scores, rig), b, min_time)})  # fmt: skip
    return rows


def peak_memory_mb() -> float:
    """Peak resident memory of this process so far, MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
