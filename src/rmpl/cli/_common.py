"""What the 3D commands share: read calibration + 2D keypoints, match views, write 3D."""

from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig

log = logging.getLogger(__name__)

OUTPUT_SUFFIXES = (".npz", ".json", ".trc", ".c3d")


def add_io_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--calib", required=True, help="calibration file or folder (any supported format)")
    parser.add_argument(
        "--keypoints", required=True, nargs="+",
        help="2D keypoints: an rmpl .npz/.json, a COCO JSON per view, or one OpenPose JSON folder per view",
    )  # fmt: skip
    parser.add_argument("--skeleton", default=None, help="2D joint set when ambiguous (body25, body25b, coco18)")
    parser.add_argument("--out", required=True, help=f"output file: {', '.join(OUTPUT_SUFFIXES)}")
    parser.add_argument("--fps", type=float, default=None, help="frame rate for TRC/C3D if the input has none")


@dataclass
class Inputs:
    """Matched inputs: keypoints (T, V, P, J, 2), scores (T, V, P, J), the rig, frames."""

    rig: Rig
    keypoints: np.ndarray
    scores: np.ndarray
    frames: np.ndarray
    fps: float | None


def check_output(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in OUTPUT_SUFFIXES:
        raise InputError(path, None, f"an output file ending in one of {', '.join(OUTPUT_SUFFIXES)}")
    return path


def load_inputs(args: argparse.Namespace) -> Inputs:
    """Read the calibration and the keypoints, and put the views in the rig's order."""
    from rmpl.io.calibration import load_rig
    from rmpl.io.keypoints import load_keypoints

    rig = load_rig(args.calib)
    kp = load_keypoints(args.keypoints, skeleton=args.skeleton)
    keypoints, scores = kp.keypoints, kp.scores
    V = keypoints.shape[1]
    views = list(kp.views)
    if set(views) == set(rig.names) and views != rig.names:
        order = [views.index(n) for n in rig.names]
        keypoints, scores = keypoints[:, order], scores[:, order]
    elif V != len(rig):
        raise InputError(
            args.keypoints[0] if len(args.keypoints) == 1 else ", ".join(args.keypoints),
            "views",
            f"{len(rig)} views to match the cameras {rig.names} of {args.calib}",
            f"{V} views {views}",
        )
    elif views != rig.names:
        log.info("matching keypoint views %s to cameras %s by order", views, rig.names)
    return Inputs(rig, keypoints, scores, np.asarray(kp.frames), kp.fps or args.fps)


def people_per_frame(inputs: Inputs) -> tuple[np.ndarray, np.ndarray]:
    """Per-person lifter input: keypoints (T, N, V, J, 2) and scores (T, N, V, J).

    With one person per view this is the input itself. With several, people are
    associated across views by geometry (:mod:`rmpl.association`).
    """
    kp, sc = inputs.keypoints, inputs.scores
    if kp.shape[2] <= 1:
        return kp.transpose(0, 2, 1, 3, 4), sc.transpose(0, 2, 1, 3)
    from rmpl.association import associate_sequence

    return associate_sequence(kp, sc, inputs.rig)


def save_result(
    path: Path,
    points: np.ndarray,
    inputs: Inputs,
    num_views: np.ndarray,
    source: str,
    error: np.ndarray | None = None,
) -> None:
    """Write (T, N, J, 3) points with per-joint view counts and a source flag."""
    from rmpl.io.poses import JointSource, Poses3D, save_poses

    seen = np.isfinite(points).all(-1)
    flag = JointSource.LIFTED if source == "lifted" else JointSource.TRIANGULATED
    flags = np.where(seen, int(flag), int(JointSource.MISSING)).astype(np.uint8)
    poses = Poses3D(
        points=points,
        scores=None if error is None else np.where(seen, 1.0, 0.0),
        flags=flags,
        num_views=num_views.astype(np.int16),
        skeleton="coco17",
        frames=inputs.frames,
        fps=inputs.fps,
        person_ids=np.arange(points.shape[1]),
    )
    save_poses(poses, path)
    log.info("wrote %s: %d frames x %d people, %.0f%% joints present",
             path, points.shape[0], points.shape[1], 100 * seen.mean())  # fmt: skip
