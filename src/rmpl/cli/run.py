"""The whole job: 2D detections (or videos) + calibration -> tracked, smoothed 3D skeletons.

Stages: detection (videos/images only), association across views, lifting (or
triangulation), tracking, smoothing, export (NPZ, JSON, TRC, C3D, BVH) and pictures
(viewer.html, skeleton.png, reprojection.png, and for videos/images the reprojection
overlays overlay_<camera>.mp4 or overlay_<camera>/).

From videos (--videos, one synchronised video per camera) or image folders (--images, one
folder of frames per camera, image i of each folder = frame i): BlazePose's networks
(needs rmpl[detect]) find up to 4 people per frame and view and follow them over frames
(--detector mediapipe: one person, MediaPipe's legacy Pose). The videos must have the same
number of frames and frame rate; the cameras of --calib are matched to the videos by name
(file name without suffix = camera name) or else by order. The 2D detections are cached in
OUT/keypoints2d.npz with a fingerprint of the inputs (names, sizes, modification times) in
OUT/keypoints2d.inputs.json: a second run on the same inputs skips detection, a run on
other inputs detects again. An interrupted detection resumes from the views already done
(OUT/.detect2d/).

The outputs change as a unit: they are written into OUT/.rmpl-staging.<pid>/ and moved in
through a journal (OUT/.rmpl-commit.json) once all are complete, so a failed or killed run
leaves the previous complete set (or, if killed while moving, a journal the next run or
reader finishes). Other files in OUT are left alone (docs/reliability.md).

With one camera (and a per-frame model), depth along the rays comes from the floor (--floor;
default: the calibration's convention), a body-size prior and each track's constant size
(rmpl.pipeline.monocular); the log says how much of each, and poses.npz/json hold the
per-joint uncertainty (the 50% radius of the depth error).

With two or more cameras a model that reads the floor (floor26) is given it too: --floor, or
by default the floor under the run's own triangulated people; report.md says which.

Besides the exports, OUT gets report.md and report.json (reprojection errors per joint, how
often each camera was excluded or missed, each person's frames, filled gaps and height, and
the view check) and OUT/pose-3d/ one TRC + C3D per person for Pose2Sim's kinematics
(--pose2sim).

Exit status: 0 done; 2 bad input; 3 a person's views disagree in most frames (its 3D is most
likely a blend of different people, or a camera is off): the outputs are written and
report.md names the cameras and frames.

Examples:
  rmpl run --calib Calib.qca.txt --keypoints pose/ --out results/
  rmpl run --calib calibration.json --keypoints shelf_dev/ --out shelf/ --method robust
  rmpl run --calib calib.toml --videos cam1.mp4 cam2.mp4 cam3.mp4 --out trial/
  rmpl run --calib calib.toml --images frames/cam1 frames/cam2 --fps 30 --out trial/
  rmpl run --calib one_camera.toml --keypoints cam1.json --floor z=0 --fps 30 --out trial/
"""

from __future__ import annotations

import argparse
import functools
import logging
from pathlib import Path

import numpy as np

from rmpl.cli._common import FLOOR_HELP, MODEL_HELP, at_least_one, count, positive
from rmpl.pipeline.association import DUPLICATE_TOLERANCE, AssociationConfig
from rmpl.pipeline.identity import IdentityConfig
from rmpl.pipeline.outputs import FORMATS

log = logging.getLogger(__name__)


def _tolerance(text: str) -> float | None:
    """``--duplicate-tolerance``: 'off' (None) or a number > 0."""
    return None if text == "off" else positive(text)


def register(parser: argparse.ArgumentParser) -> None:
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
        "frame rate, else halpe26 (per frame)",
    )
    parser.add_argument(
        "--skeleton", default=None, help="2D joint set when ambiguous (body25, body25b)"
    )
    parser.add_argument(
        "--fps", type=positive, default=None, help="frame rate if the input has none"
    )
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
        help="videos/images: 2D detector: blazepose-multi (default: up to 4 people per view, "
        "followed over frames), blazepose-multi-static, mediapipe (one person, MediaPipe's "
        "legacy Pose)",
    )
    parser.set_defaults(run=run)


def default_model(num_cameras: int, fps: float | None, method: str) -> str:
    """``rmpl run``'s model when ``--model`` is not given: the temporal model (whole tracks,
    chosen by the rule in docs/results.md) with two or more cameras and a known frame rate;
    otherwise the per-frame model ``floor26``, saying why; with one camera ``floor26`` too,
    given the floor (docs/results.md: both chosen by rules set before the runs), and
    without a floor :data:`ONE_CAMERA_NO_FLOOR` (decided when the floor is resolved)."""
    if method != "rmpl" or num_cameras < 2:
        return per_frame_model(num_cameras)
    if fps is None:
        log.warning(
            "no frame rate known (give --fps): lifting each frame with the per-frame model "
            "instead of whole tracks with the temporal model"
        )
        return PER_FRAME
    return TEMPORAL


def per_frame_model(num_cameras: int) -> str:
    """The per-frame model of ``rmpl run`` / ``rmpl lift`` when ``--model`` is not given."""
    return ONE_CAMERA if num_cameras < 2 else PER_FRAME


#: ``rmpl run``'s shipped models when ``--model`` is not given (docs/results.md says how each
#: was chosen): per frame, over whole tracks, one camera with a floor and without one, and
#: one camera with a floor and a frame rate (whole tracks; None: ``ONE_CAMERA`` per frame).
PER_FRAME, TEMPORAL, ONE_CAMERA = "floor26", "temporal26", "floor26"
ONE_CAMERA_NO_FLOOR = "default"
ONE_CAMERA_TEMPORAL: str | None = None


def _warn_unused_filter(args: argparse.Namespace) -> None:
    """--filter / --cutoff set away from their defaults do nothing with the temporal model."""
    from rmpl.inference_temporal import is_temporal_checkpoint

    changed = args.filter != "butterworth" or args.cutoff != 6.0
    if changed and args.method == "rmpl" and is_temporal_checkpoint(args.model):
        log.warning(
            "--filter / --cutoff do not apply to the temporal model (it filters with rmpl "
            "run's defaults); give --model default to filter per-frame answers your way"
        )


def _formats(text: str) -> list[str]:
    items = [f.strip().lower().lstrip(".") for f in text.split(",") if f.strip()]
    bad = [f for f in items if f not in FORMATS]
    if bad or not items:
        raise ValueError(f"--formats: expected some of {', '.join(FORMATS)}, got {text!r}")
    return items


def run(args: argparse.Namespace) -> int:
    from rmpl.cli._common import (
        check_cameras,
        check_estimated,
        load_calibration_and_2d,
        log_joint_sets,
        multi_view_floor,
        one_camera,
        run_one_camera,
        warn_unused_floor,
    )
    from rmpl.cli.lift import axis_vector
    from rmpl.pipeline.outputs import write_all, write_input_overlays
    from rmpl.pipeline.runner import RunConfig, run_with_floor

    formats = _formats(args.formats)
    out = Path(args.out)
    up = axis_vector(args.up)
    inputs = load_calibration_and_2d(args, cache=out / "keypoints2d.npz")
    check_cameras(inputs.rig, args.calib, args.method)
    auto_model = args.model is None
    args.model = args.model or default_model(len(inputs.rig), inputs.fps, args.method)
    cfg = RunConfig(
        method=args.method,
        model=args.model,
        filter=args.filter,
        cutoff=args.cutoff,
        max_gap=args.max_gap,
        min_track_frames=args.min_track,
        up=None if up is None else tuple(up),
        association=AssociationConfig(duplicate_tolerance=args.duplicate_tolerance),
        identity=IdentityConfig(people=args.people),
    )
    _warn_unused_filter(args)
    single = one_camera(inputs.rig, args.method, args.model)
    if len(inputs.rig) == 1 and args.method == "rmpl" and not single:
        log.warning(
            "ONE CAMERA with the temporal model: nothing fixes the depth along the rays "
            "(expect errors of 0.3 m or more); --model floor26 reads the floor (with none, the "
            "default one-camera path uses body size and time)"
        )
    if single:  # depth from the floor, body size and time (it says so in the log)
        poses, floor = run_one_camera(inputs, cfg, args.floor, temporal=True, auto_model=auto_model)
    else:
        poses, floor = run_with_floor(
            inputs.keypoints, inputs.scores, inputs.rig, inputs.frames, inputs.fps, cfg,
            joints=inputs.skeleton, floor=multi_view_floor(args.floor, inputs.rig, up),
        )  # fmt: skip
        warn_unused_floor(args.floor, floor, cfg)
    check_estimated(poses, args, args.method)
    log_joint_sets(inputs.skeleton, poses.skeleton)
    if not single and poses.uncertainty is not None and np.isfinite(poses.uncertainty).any():
        r = poses.uncertainty[np.isfinite(poses.uncertainty)] * 1000
        log.info(
            "temporal model: predicted error radius (50%%) median %.0f mm, 90th percentile "
            "of joints %.0f mm (per joint in poses.json/npz 'uncertainty'; the viewer colours it)",
            np.median(r), np.percentile(r, 90),
        )  # fmt: skip
    overlays = None
    if (args.videos or args.images) and not args.no_overlay:
        kind = "videos" if args.videos else "images"
        overlays = functools.partial(
            write_input_overlays, args.videos or args.images, kind, poses, inputs
        )
    report = write_all(
        poses,
        inputs,
        out,
        formats,
        pictures=not args.no_pictures,
        overlays=overlays,
        pose2sim=None if args.pose2sim == "off" else args.pose2sim,
        up=None if up is None else np.asarray(up, float),
        floor=floor,
        pose2sim_min_frames=args.pose2sim_min_frames,
    )
    return report.exit_code  # 3: a person's views disagree in most frames (outputs written)
