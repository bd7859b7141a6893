"""Lift 2D keypoints from calibrated views to 3D with the RMPL network.

Several people per view are associated across views and tracked; joints seen by one view
or none are still estimated (see the per-joint view counts in the output).

With one camera, depth along the rays comes from the floor (--floor), a body-size prior and
each track's constant size (rmpl.pipeline.monocular); the output's per-joint uncertainty is
the 50% radius of that depth error.

Example: rmpl lift --calib calib.toml --keypoints kp.json --out poses.trc
"""

from __future__ import annotations

import argparse

from rmpl.cli._common import FLOOR_HELP, add_io_arguments, axis_vector, run_single_method
from rmpl.models import MODEL_HELP, ONE_CAMERA_NO_FLOOR, PER_FRAME


def register(parser: argparse.ArgumentParser) -> None:
    add_io_arguments(parser)
    parser.add_argument(
        "--model",
        default=None,
        help=MODEL_HELP
        + f". Default: {PER_FRAME} (one camera without a floor: {ONE_CAMERA_NO_FLOOR})",
    )
    parser.add_argument(
        "--up",
        default=None,
        choices=["x", "y", "z", "-x", "-y", "-z"],
        help="world up axis (default: estimated from the cameras)",
    )
    parser.add_argument("--floor", default=None, metavar="FLOOR", help=FLOOR_HELP)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    up = axis_vector(args.up)
    return run_single_method(args, "rmpl", model=args.model, up=None if up is None else tuple(up))
