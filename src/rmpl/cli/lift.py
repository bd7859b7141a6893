"""Lift 2D keypoints from calibrated views to 3D with the RMPL network.

Example: rmpl lift --calib calib.toml --keypoints kp.json --out poses.trc
"""

from __future__ import annotations

import argparse

import numpy as np

from rmpl.cli._common import add_io_arguments, check_output, load_inputs, people_per_frame, save_result


def register(parser: argparse.ArgumentParser) -> None:
    add_io_arguments(parser)
    parser.add_argument("--model", default="default", help="shipped model name or checkpoint folder")
    parser.add_argument(
        "--up", default=None, choices=["x", "y", "z", "-x", "-y", "-z"],
        help="world up axis (default: estimated from the cameras)",
    )  # fmt: skip
    parser.add_argument("--batch-size", type=int, default=1024)
    parser.set_defaults(run=run)


def axis_vector(name: str | None) -> np.ndarray | None:
    if name is None:
        return None
    v = np.zeros(3)
    v["xyz".index(name[-1])] = -1.0 if name.startswith("-") else 1.0
    return v


def run(args: argparse.Namespace) -> int:
    from rmpl.inference import Lifter

    out = check_output(args.out)
    lifter = Lifter.from_pretrained(args.model)
    inputs = load_inputs(args)
    kp, sc = people_per_frame(inputs)  # (T, N, V, J, 2), (T, N, V, J)
    res = lifter.lift(kp, sc, inputs.rig, up=axis_vector(args.up), batch_size=args.batch_size,
                      progress=kp.shape[0] * kp.shape[1] > 4 * args.batch_size)  # fmt: skip
    save_result(out, res.points, inputs, res.num_views, "lifted")
    return 0
