"""The 2D, perturbation and synthetic options of ``rmpl evaluate`` (:mod:`rmpl.cli.evaluate`)."""

from __future__ import annotations

import argparse


def add_2d_options(parser: argparse.ArgumentParser) -> None:
    """The 2D input and the part of the dataset used."""
    parser.add_argument(
        "--keypoints",
        nargs="+",
        default=None,
        help="2D input from files (any format rmpl reads; one per camera or one file), "
        "matched to the ground truth by frame number",
    )
    parser.add_argument(
        "--2d",
        dest="two_d",
        default="auto",
        choices=("auto", "detections", "annotations", "projection"),
        help="2D source when --keypoints is not given: the dataset's detections, its 2D "
        "annotations (Shelf/Campus actorsGT, H36M 'part'), or the ground truth projected "
        "through the noise model (auto: detections if any, else projection)",
    )
    parser.add_argument("--subject", default=None, help="h36m: one subject (default: all)")
    parser.add_argument("--sequence", default=None, help="panoptic: one sequence (default: all)")
    parser.add_argument(
        "--cameras",
        default=None,
        help="panoptic: comma-separated HD cameras (default 00_03,00_06,00_12,00_13,00_23); "
        "synthetic: 'random' (default) or 'sphere' (two cameras, see --heights/--angles)",
    )
    parser.add_argument(
        "--frames",
        default="eval",
        choices=("eval", "all"),
        help="shelf/campus VoxelPose layout: the customary evaluation frames or all",
    )


def add_perturbation_options(parser: argparse.ArgumentParser) -> None:
    """Test-time perturbations, seeds and thresholds."""
    parser.add_argument(
        "--dropout", default="0", help="keypoint removal probabilities, e.g. 0,0.1,0.2,0.3"
    )
    parser.add_argument(
        "--calib-noise",
        default=None,
        metavar="DEG,MM",
        help="Gaussian extrinsic noise at test time: rotation std in degrees, camera-centre "
        "std in millimetres (thesis: 2,20)",
    )
    parser.add_argument(
        "--calib-reps", type=int, default=5, help="calibration-noise draws averaged"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of every random draw")
    parser.add_argument("--pck", type=float, default=150.0, help="PCK threshold, millimetres")


def add_synthetic_options(parser: argparse.ArgumentParser) -> None:
    """Synthetic scenes and the sphere sweep; plots."""
    parser.add_argument(
        "--holdout", default="03", help="synthetic: held-out subjects, comma-separated"
    )
    parser.add_argument(
        "--samples", type=int, default=2000, help="synthetic: scenes per view count / point"
    )
    parser.add_argument(
        "--heights", default="2.2,3.2,4", help="synthetic sphere: camera heights, metres"
    )
    parser.add_argument(
        "--angles",
        default=",".join(str(a) for a in range(10, 181, 10)),
        help="synthetic sphere: horizontal angles between the two cameras, degrees",
    )
    parser.add_argument(
        "--radius", type=float, default=6.0, help="synthetic sphere: radius, metres"
    )
    parser.add_argument("--no-plots", action="store_true", help="tables only")
