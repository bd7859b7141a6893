"""The whole job: 2D detections (or videos) + calibration -> tracked, smoothed 3D skeletons.

Stages: detection (videos/images only), association across views, lifting (or
triangulation), tracking, smoothing, export (NPZ, JSON, TRC, C3D, BVH) and pictures
(viewer.html, skeleton.png, reprojection.png, and for videos/images the reprojection
overlays overlay_<camera>.mp4 or overlay_<camera>/).

From videos (--videos, one synchronised video per camera) or image folders (--images, one
folder of frames per camera, image i of each folder = frame i): MoveNet MultiPose finds up
to 6 people per frame and view, BlazePose's landmark network draws each (feet included) and
follows them over frames (needs rmpl[detect]; --detector blazepose-multi: the former
detector; mediapipe: one person, MediaPipe's legacy Pose). The videos must have the same
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

from rmpl.cli._run_arguments import add_run_arguments, formats_of
from rmpl.pipeline.association import AssociationConfig
from rmpl.pipeline.identity import IdentityConfig

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    add_run_arguments(parser)
    parser.set_defaults(run=run)


def _log_uncertainty(poses) -> None:
    """The temporal model's predicted error radius, in one line."""
    if poses.uncertainty is None or not np.isfinite(poses.uncertainty).any():
        return
    r = poses.uncertainty[np.isfinite(poses.uncertainty)] * 1000
    log.info(
        "temporal model: predicted error radius (50%%) median %.0f mm, 90th percentile "
        "of joints %.0f mm (per joint in poses.json/npz 'uncertainty'; the viewer colours it)",
        np.median(r), np.percentile(r, 90),
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from rmpl.calibration.sync import synced_inputs
    from rmpl.cli._common import (
        axis_vector,
        check_cameras,
        check_estimated,
        load_calibration_and_2d,
        log_joint_sets,
    )
    from rmpl.models import choose_model
    from rmpl.pipeline.job import estimate_poses
    from rmpl.pipeline.outputs import write_all, write_input_overlays
    from rmpl.pipeline.runner import RunConfig
    from rmpl.project.unused import warn_unused_options

    formats = formats_of(args.formats)
    out = Path(args.out)
    up = axis_vector(args.up)
    inputs = load_calibration_and_2d(args, cache=out / "keypoints2d.npz")
    inputs = synced_inputs(inputs, getattr(args, "sync", None), ", ".join(args.keypoints or []))
    check_cameras(inputs.rig, args.calib, args.method)
    auto_model = args.model is None
    args.model = args.model or choose_model(len(inputs.rig), inputs.fps, args.method)
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
    warn_unused_options(args, inputs.fps, auto_model)  # said, never dropped in silence
    poses, floor, single = estimate_poses(inputs, cfg, args.floor, auto_model=auto_model)
    check_estimated(poses, args, args.method)
    log_joint_sets(inputs.skeleton, poses.skeleton)
    if not single:
        _log_uncertainty(poses)
    overlays = None
    if (args.videos or args.images) and not args.no_overlay:
        kind = "videos" if args.videos else "images"
        overlays = functools.partial(
            write_input_overlays, args.videos or args.images, kind, poses, inputs
        )
    report = write_all(
        poses, inputs, out, formats, pictures=not args.no_pictures, overlays=overlays,
        pose2sim=None if args.pose2sim == "off" else args.pose2sim,
        up=None if up is None else np.asarray(up, float), floor=floor,
        pose2sim_min_frames=args.pose2sim_min_frames,
    )  # fmt: skip
    return report.exit_code  # 3: a person's views disagree in most frames (outputs written)
