"""Run the whole job on the embedded example: a 4-camera walk, lifted, smoothed, exported.

Writes poses.{npz,json,trc,c3d,bvh}, report.md/report.json, pose-3d/ (the Pose2Sim files),
viewer.html (open it in a browser), skeleton.png and reprojection.png into --out, and
prints the error of RMPL and of robust triangulation against the example's ground truth.
The example was made by rmpl itself (rmpl.benchmarks.make_example): a held-out motion-capture
walk retargeted onto an anny body, rendered from 4 synthetic cameras, with MediaPipe
BlazePose's 2D detections of the renders.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from rmpl.models import MODEL_HELP

log = logging.getLogger(__name__)

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "walk"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="out/example", help="output folder")
    parser.add_argument(
        "--model",
        default="floor26",
        help=MODEL_HELP,
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from rmpl.cli._common import load_calibration_and_2d
    from rmpl.metrics import mpjpe
    from rmpl.pipeline.outputs import FORMATS, write_all
    from rmpl.pipeline.runner import RunConfig, run_with_floor
    from rmpl.skeleton import KP_STAR

    ns = argparse.Namespace(
        calib=str(EXAMPLE / "calibration.toml"),
        keypoints=[str(EXAMPLE / "keypoints.json")],
        skeleton=None,
        fps=None,
    )
    inputs = load_calibration_and_2d(ns)
    gt = np.load(EXAMPLE / "ground_truth.npz")["points"][:, 0, :17]  # (T, 17, 3)
    out = Path(args.out)
    results = {}
    for method in ("rmpl", "robust", "triangulate"):
        cfg = RunConfig(method=method, model=args.model)
        poses, floor = run_with_floor(
            inputs.keypoints, inputs.scores, inputs.rig, inputs.frames, inputs.fps, cfg,
            joints=inputs.skeleton,
        )  # fmt: skip
        results[method] = poses.points[:, 0, :17]  # scored on COCO-17 (HALPE-26's first 17)
        if method == "rmpl":
            write_all(poses, inputs, out, list(FORMATS), floor=floor)
    sc = inputs.scores
    seen = sc[:, :, 0] > 0
    err2d = np.linalg.norm(inputs.keypoints[:, :, 0] - inputs.rig.project(gt), axis=-1)[seen]
    print(
        f"example: {len(sc)} frames, {len(inputs.rig)} views, "
        f"{100 * (sc == 0).mean():.0f}% of 2D keypoints missing; the 2D lies a median of "
        f"{np.median(err2d):.1f} px (mean {err2d.mean():.1f}) from the projected ground truth"
    )
    for method, label in (
        ("rmpl", "RMPL"),
        ("robust", "robust triangulation"),
        ("triangulate", "triangulation (DLT)"),
    ):
        p = results[method]
        cov = 100 * np.isfinite(p).all(-1).mean()
        print(
            f"  {label:21s} MPJPE {1000 * mpjpe(p, gt):5.1f} mm"
            f"   KP* {1000 * mpjpe(p, gt, KP_STAR):5.1f} mm"
            f"   ({cov:.0f}% of joints estimated)"
        )
    print(
        f"wrote {out}: poses.{{npz,json,trc,c3d,bvh}}, report.md, report.json, pose-3d/, "
        "viewer.html, skeleton.png, reprojection.png"
    )
    return 0
