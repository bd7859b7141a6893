"""The options of ``rmpl run`` (:mod:`rmpl.cli.run`)."""

from __future__ import annotations

import argparse

from rmpl.cli._common import FLOOR_HELP, at_least_one, count, positive
from rmpl.models import MODEL_HELP, PER_FRAME
from rmpl.pipeline.association import DUPLICATE_TOLERANCE
from rmpl.pipeline.outputs import FORMATS


def _tolerance(text: str) -> float | None:
    """``--duplicate-tolerance``: 'off' (None) or a number > 0."""
    return None if text == "off" else positive(text)


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``rmpl run``."""
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument(
        "--keypoints", nargs="+", help="2D files/folders (OpenPose, COCO, rmpl, Shelf 4D)"
    )
    src.add_argument(
        "--videos", nargs="+", help="one synchronised video per camera (needs rmpl[detect])"
    )
    src.add_argument("--images", nargs="+", help="one image folder per camera (needs rmpl[detect])")
    parser.add_argument("--calib", required=True, help="calibration file or folder")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--method", default="rmpl", choices=["rmpl", "triangulate", "robust"])
    parser.add_argument(
        "--model",
        default=None,
        help=MODEL_HELP + ". Default: the temporal model with two or more cameras and a known "
        f"frame rate, else {PER_FRAME} (per frame); rmpl models says when each is picked",
    )
    parser.add_argument(
        "--skeleton", default=None, help="2D joint set when ambiguous (body25, body25b)"
    )
    parser.add_argument(
        "--fps", type=positive, default=None, help="frame rate if the input has none"
    )
    parser.add_argument(
        "--sync", default=None, metavar="SYNC", help="sync.json (rmpl sync) or 'auto': put "
        "every camera on the first one's clock (the report states the offsets)"
    )  # fmt: skip
    _add_tracking_arguments(parser)
    _add_output_arguments(parser)


def _add_tracking_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--filter", default="butterworth", choices=["butterworth", "one-euro", "none"]
    )
    parser.add_argument(
        "--cutoff", type=positive, default=6.0, help="Butterworth cut-off, Hz (below fps / 2)"
    )
    parser.add_argument(
        "--max-gap", type=count, default=20, help="fill gaps up to N frames (0: off)"
    )
    parser.add_argument(
        "--min-track",
        type=at_least_one,
        default=3,
        help="drop people present in fewer than N frames (ghosts; 1 keeps all)",
    )
    parser.add_argument(
        "--people",
        type=at_least_one,
        default=None,
        metavar="N",
        help="how many people were filmed, when known: shorter tracks join the others or go",
    )
    parser.add_argument(
        "--duplicate-tolerance",
        type=_tolerance,
        default=DUPLICATE_TOLERANCE,
        metavar="T",
        help="drop a 3D person whose limbs reproject within T x the other's size onto a "
        f"view-disjoint other's detections (one person split in two); 'off' keeps all "
        f"(default {DUPLICATE_TOLERANCE})",
    )
    parser.add_argument(
        "--up",
        default=None,
        choices=["x", "y", "z", "-x", "-y", "-z"],
        help="world up axis (default: from the cameras)",
    )
    parser.add_argument("--floor", default=None, metavar="FLOOR", help=FLOOR_HELP)


def _add_output_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--formats",
        default="npz,json,trc,c3d",
        help=f"any of {','.join(FORMATS)} (BVH: one file per person, poses_p<id>.bvh)",
    )
    parser.add_argument(
        "--pose2sim",
        default="pose2sim-y-up",
        choices=["pose2sim-y-up", "z-up", "off"],
        help="one TRC + C3D per person in OUT/pose-3d/ for Pose2Sim/OpenSim (Pose2Sim's "
        "COCO_17 or HALPE_26 marker names, by the model's joint set): in Pose2Sim's Y-up axes "
        "(default), the world's Z-up axes, or off",
    )
    parser.add_argument(
        "--pose2sim-min-frames",
        type=at_least_one,
        default=None,
        metavar="N",
        help="people in fewer frames get no TRC + C3D of their own in pose-3d/ (they stay in "
        "the other exports; default: one second of frames)",
    )
    parser.add_argument("--no-pictures", action="store_true", help="skip viewer.html and the PNGs")
    parser.add_argument(
        "--no-overlay",
        action="store_true",
        help="videos/images: skip drawing the result onto the input frames",
    )
    parser.add_argument(
        "--detector",
        default=None,
        help="videos/images: 2D detector: movenet-blazepose (default: MoveNet finds up to 6 "
        "people per view, BlazePose draws each with heels and toes, followed over frames), "
        "movenet-blazepose-static, movenet-blazepose-fast (MoveNet every 5th frame while "
        "everyone is followed), movenet (COCO-17, no feet), blazepose-multi (the former "
        "default, up to 4 people), blazepose-multi-static, mediapipe (one person, MediaPipe's "
        "legacy Pose)",
    )
    parser.add_argument(
        "--detect-workers",
        type=int,
        default=None,
        metavar="N",
        help="videos/images: cameras detected at once, as tasks of a local Ray (rmpl[ray]); "
        "the same 2D as one after the other (default 1)",
    )


def formats_of(text: str) -> list[str]:
    """``--formats``: the export formats, checked."""
    items = [f.strip().lower().lstrip(".") for f in text.split(",") if f.strip()]
    bad = [f for f in items if f not in FORMATS]
    if bad or not items:
        raise ValueError(f"--formats: expected some of {', '.join(FORMATS)}, got {text!r}")
    return items
