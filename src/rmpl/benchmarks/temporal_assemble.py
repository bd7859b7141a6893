"""Ways to assemble a temporal model's answer, on synthetic windows (the shipped choice).

Usage: python -m rmpl.benchmarks.temporal_assemble SEQBANK [MODEL] [--seed 12345] [--windows 64]

For 2, 3 and 5 views, on windows of held-out motion (CMU subject 03, the temporal detector
model; seed 12345 = the validation windows the rule used, 777 = the evaluation windows),
KP* MPJPE in mm over all joints in frames with 2D, the joints `triangulate+filter` estimates
("common") and the joints fewer than two views see ("hard"), of:

- temp: the network's output;
- H1: the per-frame answer where >= 2 views see the joint, filtered, the network's elsewhere;
- H2: the per-frame answer where >= 2 views see the joint, the network's elsewhere, then
  filtered (what ``"assemble": "filtered"`` does: rmpl.inference_temporal.assemble_track);
- H3: H2's filtered values only where >= 2 views see the joint, the network's elsewhere.

The filters are rmpl run's defaults (rmpl.pipeline.runner.smooth), cut-off min(6, 0.45 fps).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from rmpl.benchmarks._common import run_main
from rmpl.data.sequences import SequenceBank, SequenceSource
from rmpl.pipeline.runner import RunConfig, smooth
from rmpl.skeleton import KP_STAR
from rmpl.training.temporal import load_temporal

#: The shipped COCO-17 temporal model (``--model temporal``).
SHIPPED = Path(__file__).resolve().parents[1] / "weights" / "temporal"


def filtered(X: np.ndarray, times: np.ndarray) -> np.ndarray:
    """rmpl run's filters on each window (B, T, J, 3), at its own rate."""
    out = np.full_like(X, np.nan)
    for i in range(len(X)):
        rate = 1.0 / float(np.mean(np.diff(times[i])))
        out[i] = smooth(X[i][:, None], rate, RunConfig(cutoff=min(6.0, 0.45 * rate)))[0][:, 0]
    return out


def main(argv: list[str] | None = None) -> int:
    from rmpl.benchmarks.temporal_synthetic import dlt_filtered

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank")
    ap.add_argument("model", nargs="?", default=str(SHIPPED), help="a temporal checkpoint")
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--windows", type=int, default=64)
    a = ap.parse_args(argv)
    torch.set_num_threads(2)
    _, val = SequenceBank.load(a.bank).split(["03"])
    m = load_temporal(a.model)[0]
    m.use_onnx()
    kp = list(KP_STAR)
    means: dict[str, list[float]] = {}
    print("| views | answer | all | common | hard |")
    print("|---|---|---:|---:|---:|")
    for v in (2, 3, 5):
        b = SequenceSource(val, seed=a.seed).batch(a.windows, m.config.window, v, train=False)
        rays, scores, times = (torch.from_numpy(x) for x in (b.rays, b.scores, b.times))
        with torch.no_grad():
            net = m(rays, scores, times)[0].numpy()
            frame = m.encode_frames(rays, scores)[0].numpy()
        two = ((b.scores > 0).sum(2) >= 2)[..., None]  # (B, T, J, 1)
        seen = (b.scores > 0).any((2, 3))[..., None].repeat(17, -1)
        s1 = filtered(np.where(two, frame, np.nan), b.times)
        s2 = filtered(np.where(two, frame, net), b.times)
        answers = {
            "temp": net,
            "H1": np.where(two & np.isfinite(s1), s1, net),
            "H2": np.where(np.isfinite(s2), s2, net),
            "H3": np.where(two & np.isfinite(s2), s2, net),
        }
        common = np.isfinite(dlt_filtered(b)).all(-1)
        hard = ~two[..., 0] & seen
        for name, x in answers.items():
            e = np.linalg.norm(x - b.target, axis=-1)[..., kp] * 1000
            cells = [e[mask[..., kp]].mean() for mask in (seen, common, hard)]
            means.setdefault(name, []).append(cells[0])
            print(f"| {v} | {name} | " + " | ".join(f"{c:.1f}" for c in cells) + " |")
    print("mean over 2, 3, 5 views, all joints:",
          ", ".join(f"{k} {np.mean(x):.1f}" for k, x in means.items()))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
