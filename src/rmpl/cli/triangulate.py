"""Triangulate 2D keypoints from calibrated views (confidence-weighted DLT, or --robust).

Example: rmpl triangulate --calib calib.toml --keypoints kp.json --out poses.c3d --robust
"""

from __future__ import annotations

import argparse

import numpy as np

from rmpl.cli._common import add_io_arguments, check_output, load_inputs, people_per_frame, save_result


def register(parser: argparse.ArgumentParser) -> None:
    add_io_arguments(parser)
    parser.add_argument("--robust", action="store_true",
                        help="exclude views until the reprojection error is below --max-error")  # fmt: skip
    parser.add_argument("--min-score", type=float, default=None,
                        help="ignore keypoints below this confidence (default 0, or 0.3 with --robust)")  # fmt: skip
    parser.add_argument("--max-error", type=float, default=15.0, help="pixels, with --robust")
    parser.add_argument("--no-swap", action="store_true", help="with --robust: skip the left/right swap check")
    parser.add_argument("--chunk", type=int, default=500, help="frames per progress step")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from rmpl.geometry.triangulate import triangulate, triangulate_robust
    from rmpl.skeleton import COCO17

    out = check_output(args.out)
    inputs = load_inputs(args)
    kp, sc = people_per_frame(inputs)
    T = kp.shape[0]
    points = np.full((*kp.shape[:2], kp.shape[-2], 3), np.nan)
    nviews = np.zeros(sc.shape[:2] + sc.shape[-1:], np.int16)
    for s in tqdm(range(0, T, args.chunk), desc="triangulate", unit="chunk", disable=T <= args.chunk):
        sl = slice(s, s + args.chunk)
        if args.robust:
            res = triangulate_robust(
                kp[sl], sc[sl], inputs.rig,
                min_score=0.3 if args.min_score is None else args.min_score,
                max_error=args.max_error,
                swap_pairs=None if args.no_swap else COCO17.flip_pairs,
            )  # fmt: skip
        else:
            res = triangulate(kp[sl], sc[sl], inputs.rig, min_score=args.min_score or 0.0)
        points[sl], nviews[sl] = res.points, res.num_views
    save_result(out, points, inputs, nviews, "triangulated")
    return 0
