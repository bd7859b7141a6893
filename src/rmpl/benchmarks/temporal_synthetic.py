"""Temporal models on held-out synthetic windows (CMU subject 03, the temporal detector model).

Usage: python -m rmpl.benchmarks.temporal_synthetic SEQBANK MODEL [MODEL ...] [--windows 128]
Prints per view count: KP* MPJPE (mm) of each temporal model (its answer assembled as its
lifter does: ``"inference": {"assemble": ...}`` in its config.json) and of its per-frame model
alone, over the frames with any keypoint; on the joints fewer than two views see; the DLT of
the same windows after rmpl run's filters (triangulate+filter, identity known); and the share
of errors inside the predicted 50% / 90% radii (with the checkpoint's per-view-count
calibration when it has one).
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from rmpl.benchmarks._common import run_main
from rmpl.data.sequences import SequenceBank, SequenceSource
from rmpl.geometry.triangulate import _dlt
from rmpl.inference_temporal import RadiusCalibration, TemporalLifter, TrackResult
from rmpl.pipeline.runner import RunConfig, smooth
from rmpl.skeleton import KP_STAR
from rmpl.training.temporal import assembled_windows, load_temporal


def dlt_filtered(b) -> np.ndarray:
    """Weighted DLT per frame, then rmpl run's Hampel / gap filling / Butterworth: (B, T, J, 3)."""
    from rmpl.geometry.rays import pixel_to_normalized

    ok = b.scores > 0
    B, T, V, J = ok.shape
    K = np.repeat(b.K[:, None], T, 1)
    xy = pixel_to_normalized(np.where(ok[..., None], b.keypoints, 0.0), K[..., None, :, :], None)
    P = np.concatenate([b.R, b.t[..., None]], -1)
    P = np.repeat(P[:, None], T, 1)
    X = _dlt(xy.reshape(B * T, V, J, 2), P.reshape(B * T, V, 3, 4), np.where(ok, b.scores, 0.0)
             .reshape(B * T, V, J)).reshape(B, T, J, 3)  # fmt: skip
    X[(ok.sum(2) < 2)] = np.nan
    out = np.full_like(X, np.nan)
    for i in range(B):  # each window at its own rate
        rate = 1.0 / float(np.mean(np.diff(b.times[i])))
        cfg = RunConfig(cutoff=min(6.0, 0.45 * rate))
        out[i] = smooth(X[i][:, None], rate, cfg)[0][:, 0]
    return out


def _by_window(m, rays, scores, times):
    """The model on its own window length: (B, T) windows cut into (B * T / w, w)."""
    B, T = times.shape
    w = m.config.window
    if w >= T or T % w:
        return m(rays, scores, times)
    n = T // w
    cut = lambda x: x.reshape(B * n, w, *x.shape[2:])  # noqa: E731
    points, sigma = m(cut(rays), cut(scores), cut(times))
    return points.reshape(B, T, *points.shape[2:]), sigma.reshape(B, T, -1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank")
    ap.add_argument("models", nargs="+")
    ap.add_argument("--windows", type=int, default=128)
    ap.add_argument("--views", default="2,3,5")
    a = ap.parse_args(argv)
    torch.set_num_threads(2)
    _, val = SequenceBank.load(a.bank).split(["03"])
    loaded = {m: load_temporal(m) for m in a.models}
    models = {m: x[0] for m, x in loaded.items()}
    calib = {m: RadiusCalibration.from_meta(x[1]) for m, x in loaded.items()}
    assemble = {m: TemporalLifter(*x, onnx=False).assemble for m, x in loaded.items()}
    for m in models.values():
        if m.config.frozen_encoder:  # a fine-tuned per-frame model runs in torch
            m.use_onnx()
    window = max(m.config.window for m in models.values())  # shorter models: cut windows
    kp = list(KP_STAR)
    for v in [int(x) for x in a.views.split(",")]:
        b = SequenceSource(val, seed=777).batch(a.windows, window, v, train=False)
        rays, scores, times = (torch.from_numpy(x) for x in (b.rays, b.scores, b.times))
        seen = (b.scores > 0).any((2, 3))[..., None].repeat(len(kp), -1)  # frame has 2D
        hard = ((b.scores > 0).sum(2)[..., kp] < 2) & seen
        print(f"== {v} views ({a.windows} windows of {window} frames)")
        tri = np.linalg.norm(dlt_filtered(b) - b.target, axis=-1)[..., kp]
        common = seen & np.isfinite(tri)
        print(f"  triangulate+filter: common {tri[common].mean() * 1000:7.1f}  "
              f"coverage {common.sum() / seen.sum() * 100:5.1f}%")  # fmt: skip
        for name, m in models.items():
            with torch.no_grad():
                points, sigma = _by_window(m, rays, scores, times)
                frame = m.encode_frames(rays, scores)[0]
            en = np.linalg.norm(points.numpy() - b.target, axis=-1)[..., kp]
            ef = np.linalg.norm(frame.numpy() - b.target, axis=-1)[..., kp]
            answer = points.numpy()
            if assemble[name] == "filtered":  # as the lifter assembles it
                answer = assembled_windows(m, b, "filtered")[0]
            e = np.linalg.norm(answer - b.target, axis=-1)[..., kp]
            res = TrackResult(answer, sigma.numpy(), (b.scores > 0).sum(2), calib[name])
            r50, r90 = res.radius(0.5)[..., kp], res.radius(0.9)[..., kp]
            ok = np.isfinite(e)
            c50, c90 = np.mean(e[ok] < r50[ok]), np.mean(e[ok] < r90[ok])
            print(f"  {name} ({assemble[name]}): answer common {e[common].mean() * 1000:7.1f}  "
                  f"all {e[seen].mean() * 1000:7.1f}  hard {e[hard].mean() * 1000:7.1f}  "
                  f"missing frames {e[~seen].mean() * 1000:7.1f} | network common "
                  f"{en[common].mean() * 1000:7.1f}  all {en[seen].mean() * 1000:7.1f}  hard "
                  f"{en[hard].mean() * 1000:7.1f} | per-frame common "
                  f"{ef[common].mean() * 1000:7.1f}  all {ef[seen].mean() * 1000:7.1f}  "
                  f"hard {ef[hard].mean() * 1000:7.1f}"
                  f" | inside 50% {c50 * 100:4.1f}%  90% {c90 * 100:4.1f}%")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
