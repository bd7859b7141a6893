"""Run the whole job on the embedded example: a 4-camera walk, lifted, smoothed, exported.

Writes poses.{npz,json,trc,c3d,bvh}, report.md/report.json, pose-3d/ (the Pose2Sim files),
viewer.html (open it in a browser), skeleton.png and reprojection.png into --out, and
prints the error of RMPL, robust triangulation and triangulation against the example's
ground truth, with all 4 cameras and with 2 (the mean over the 6 pairs), and which wins
where. The example was made by rmpl itself (rmpl benchmark make_example): a held-out
motion-capture walk retargeted onto an anny body, rendered from 4 synthetic cameras, with
MediaPipe BlazePose's 2D detections of the renders.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from rmpl.models import MODEL_HELP

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="out/example", help="output folder")
    parser.add_argument("--model", default="floor26", help=MODEL_HELP)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from rmpl.evaluate.example import METHODS, example_inputs, score_methods, verdict
    from rmpl.pipeline.outputs import FORMATS, write_all

    inputs, gt = example_inputs()
    out = Path(args.out)

    def keep(poses, floor):
        write_all(poses, inputs, out, list(FORMATS), floor=floor)

    scores = score_methods(inputs, gt, args.model, keep)
    sc = inputs.scores
    seen = sc[:, :, 0] > 0
    err2d = np.linalg.norm(inputs.keypoints[:, :, 0] - inputs.rig.project(gt), axis=-1)[seen]
    print(
        f"example: {len(sc)} frames, {len(inputs.rig)} views, "
        f"{100 * (sc == 0).mean():.0f}% of 2D keypoints missing; the 2D lies a median of "
        f"{np.median(err2d):.1f} px (mean {err2d.mean():.1f}) from the projected ground truth"
    )
    for setting, by_method in scores.items():
        print(f"{setting}{' (mean of the 6 pairs)' if setting == '2 cameras' else ''}:")
        for method, s in by_method.items():
            print(
                f"  {METHODS[method]:21s} MPJPE {s.mpjpe:5.1f} mm   KP* {s.kp_star:5.1f} mm"
                f"   ({s.coverage:.0f}% of joints estimated)"
            )
    print(verdict(scores))
    print(
        f"wrote {out}: poses.{{npz,json,trc,c3d,bvh}}, report.md, report.json, pose-3d/, "
        "viewer.html, skeleton.png, reprojection.png"
    )
    return 0
