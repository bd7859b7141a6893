"""Triangulate 2D keypoints from calibrated views (confidence-weighted DLT, or --robust).

--robust is Pose2Sim's method, searched exhaustively: views below --min-score are dropped,
then views are excluded until the reprojection error is below --max-error pixels, with a
left/right swap check. Several people per view are associated across views and tracked.

Example: rmpl triangulate --calib calib.toml --keypoints pose/ --out trial.c3d --robust
"""

from __future__ import annotations

import argparse

from rmpl.cli._common import add_io_arguments, fraction, positive, run_single_method


def register(parser: argparse.ArgumentParser) -> None:
    add_io_arguments(parser)
    parser.add_argument(
        "--robust",
        action="store_true",
        help="exclude views until the reprojection error is below --max-error",
    )
    parser.add_argument(
        "--min-score",
        type=fraction,
        default=None,
        help="ignore keypoints below this confidence (default 0, or 0.3 with --robust)",
    )
    parser.add_argument("--max-error", type=positive, default=15.0, help="pixels, with --robust")
    parser.add_argument(
        "--no-swap", action="store_true", help="with --robust: skip the left/right swap check"
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    return run_single_method(
        args,
        "robust" if args.robust else "triangulate",
        min_score=args.min_score,
        max_error=args.max_error,
        swap_check=not args.no_swap,
    )
