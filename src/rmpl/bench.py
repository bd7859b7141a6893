"""Speed and memory of the lifter presets and of triangulation, on this machine.

Every figure is frames per second, where a frame is one person seen by V views
(thesis table 6.7). Models run untrained weights: speed does not depend on training.
"""

from __future__ import annotations

import resource
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.geometry.triangulate import triangulate, triangulate_robust
from rmpl.model.export import OnnxLifter
from rmpl.model.lifter import PRESETS, RMPL

__all__ = [
    "long_sequence_memory",
    "markdown",
    "run_bench",
    "synthetic_inputs",
    "temporal_track",
]


def synthetic_inputs(batch: int, views: int, seed: int = 0):
    """Random rays/scores plus matching pixels and a rig, for timing."""
    rng = np.random.default_rng(seed)
    ang = np.linspace(0, 2 * np.pi, views, endpoint=False)
    K = np.array([[1000.0, 0, 500], [0, 1000, 400], [0, 0, 1]])
    cams = tuple(
        Camera(
            K,
            *look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 2.0]), np.array([0, 0, 1.0])),
            size=(1000, 800),
            name=str(i),
        )
        for i, a in enumerate(ang)
    )
    rig = Rig(cams)
    X = rng.uniform(-0.4, 0.4, (batch, 17, 3)) + [0, 0, 1]
    kp = rig.project(X) + rng.normal(0, 2, (batch, views, 17, 2))
    scores = rng.uniform(0.3, 1.0, (batch, views, 17))
    from rmpl.geometry.rays import rays_from_keypoints

    rays = rays_from_keypoints(kp, rig).astype(np.float32)
    return rays, scores.astype(np.float32), kp, rig


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

    torch.set_num_threads(2)
    runners = _runners(_models(presets), backends)
    rows = []
    jobs = [(v, b) for v in views for b in batches]
    for v, b in tqdm(jobs, desc="bench", disable=not progress):
        rays, scores, kp, rig = synthetic_inputs(b, v)
        with torch.no_grad():
            for (name, backend), fn in runners.items():
                rate = _rate(lambda fn=fn, r=rays, s=scores: fn(r, s), b, min_time)
                rows.append(_row(f"rmpl-{name}", backend, v, b, rate))
        if v >= 2:
            for method, f in (
                ("triangulate", triangulate),
                ("triangulate_robust", triangulate_robust),
            ):
                rate = _rate(lambda f=f, k=kp, s=scores, g=rig: f(k, s, g), b, min_time)
                rows.append(_row(method, "numpy", v, b, rate))
    return rows


def _models(presets) -> dict[str, RMPL]:
    """One model per preset name; "default" is the shipped checkpoint when there is one,
    an unknown name the "small" preset."""
    from rmpl.inference import PRETRAINED

    models = {}
    for name in presets:
        if name == "default" and (PRETRAINED["default"] / "config.json").is_file():
            from rmpl.training.loop import load_checkpoint

            models[name] = load_checkpoint(PRETRAINED["default"])[0]
        else:
            models[name] = RMPL(PRESETS[name if name in PRESETS else "small"]).eval()
    return models


def _runners(models: dict[str, RMPL], backends) -> dict[tuple[str, str], Callable]:
    """(model name, backend) -> a function of (rays, scores)."""
    runners = {}
    for name, model in models.items():
        if "torch" in backends:
            runners[(name, "torch")] = lambda r, s, m=model: m(
                torch.from_numpy(r), torch.from_numpy(s)
            )
        if "onnx" in backends:
            runners[(name, "onnx")] = OnnxLifter(model)
    return runners


def _row(method: str, backend: str, views: int, batch: int, fps: float) -> dict:
    return {"method": method, "backend": backend, "views": views, "batch": batch, "fps": fps}


def peak_memory_mb() -> float:
    """Peak resident memory of this process so far, MB.

    Linux's ``VmHWM`` (reset by ``exec``, so a child started by :func:`subprocess.run`
    reports its own peak); ``ru_maxrss`` elsewhere, which a child inherits from its parent.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return float(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def markdown(rows: list[dict]) -> str:
    """One table per (method, backend): rows = views, columns = batch sizes (frames/s)."""
    out = []
    keys = sorted({(r["method"], r["backend"]) for r in rows}, key=lambda k: (k[0], k[1]))
    batches = sorted({r["batch"] for r in rows})
    for method, backend in keys:
        sel = [r for r in rows if r["method"] == method and r["backend"] == backend]
        out.append(f"**{method}** ({backend}), frames/s\n")
        out.append("| views | " + " | ".join(f"batch {b}" for b in batches) + " |")
        out.append("|---:|" + "---:|" * len(batches))
        for v in sorted({r["views"] for r in sel}):
            cells = {r["batch"]: r["fps"] for r in sel if r["views"] == v}
            out.append(
                f"| {v} | "
                + " | ".join(f"{cells[b]:.0f}" if b in cells else "—" for b in batches)
                + " |"
            )
        out.append("")
    return "\n".join(out)


def _child(call: str) -> list:
    """Run ``rmpl.bench.<call>`` in a fresh process (its peak memory is its own)."""
    import json
    import subprocess
    import sys

    code = f"import json, rmpl.bench as b; print(json.dumps(b.{call}))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the benchmark child failed:\n{done.stderr.strip()}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def temporal_track(frames: int, views: int = 4) -> tuple[float, float]:
    """Lift one ``frames``-long track of ``views`` views with the temporal model (the shipped
    one, else an untrained one on the default per-frame model) in a fresh process.

    Returns:
        (frames per second of ``TemporalLifter.lift_track``, peak resident memory, MB).
    """
    fps, mb = _child(f"_track_long({int(frames)}, {int(views)})")
    return float(fps), float(mb)


def _track_long(frames: int, views: int) -> tuple[float, float]:
    """The child of :func:`temporal_track`."""
    from rmpl.inference_temporal import PRETRAINED_TEMPORAL, TemporalLifter
    from rmpl.model.temporal import TemporalRMPL

    torch.set_num_threads(2)
    rays, scores, kp, rig = synthetic_inputs(frames, views)
    del rays
    if (PRETRAINED_TEMPORAL["temporal"] / "config.json").is_file():
        lifter = TemporalLifter.from_pretrained()
    else:
        lifter = TemporalLifter(TemporalRMPL(_default_lifter().model))
    start = time.perf_counter()
    lifter.lift_track(kp, scores, rig, fps=30.0)
    return frames / (time.perf_counter() - start), peak_memory_mb()


def long_sequence_memory(frames: int, views: int = 4) -> tuple[float, float]:
    """Lift a long random sequence with the default model in a fresh process.

    Returns:
        (peak resident memory of that process, MB; seconds spent in ``Lifter.lift``). The
        fresh process keeps the benchmark's own allocations out of the peak.
    """
    mb, seconds = _child(f"_lift_long({int(frames)}, {int(views)})")
    return float(mb), float(seconds)


def _default_lifter():
    """The shipped default model, or an untrained ``small`` one where none is shipped."""
    from rmpl.inference import PRETRAINED, Lifter

    if (PRETRAINED["default"] / "config.json").is_file():
        return Lifter.from_pretrained()
    return Lifter(RMPL(PRESETS["small"]))


def _lift_long(frames: int, views: int) -> tuple[float, float]:
    """The child of :func:`long_sequence_memory`."""
    torch.set_num_threads(2)
    rays, scores, kp, rig = synthetic_inputs(frames, views)
    del rays
    lifter = _default_lifter()
    start = time.perf_counter()
    lifter.lift(kp, scores, rig)
    return peak_memory_mb(), time.perf_counter() - start
