"""What the 3D commands share: read calibration + 2D input, match views to cameras."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig

#: ``--floor`` help of ``rmpl run`` and ``rmpl lift``.
FLOOR_HELP = (
    "the floor plane, read by the models that take it (floor26, and with one camera the "
    "depth cues). AXIS=H (AXIS one of x, y, z, -x, -y, -z pointing up; e.g. z=0: z up, floor "
    "at z = 0) or nx,ny,nz,d (the plane n . X = d, n pointing up); or a poses file "
    "(.npz/.json/.trc) of a multi-view run of the same rig to estimate it from; or 'none'. "
    "Default: with two or more cameras, estimated from the run's triangulated people; with "
    "one, the calibration's convention (the cameras upright about a world axis, rolled less "
    "than 30 deg, the floor at 0 along it) when it has one"
)

log = logging.getLogger(__name__)

OUTPUT_SUFFIXES = (".npz", ".json", ".trc", ".c3d")


def _number(kind, test, expected: str):
    """An argparse ``type`` refusing impossible values at parse time (exit 2, usage line)."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if not test(value):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text}")
        return value

    parse.__name__ = expected  # argparse names the type in its messages
    return parse


positive = _number(float, lambda x: x > 0 and x < float("inf"), "a number > 0")
fraction = _number(float, lambda x: 0 <= x <= 1, "a confidence in [0, 1]")
count = _number(int, lambda x: x >= 0, "an integer >= 0")
at_least_one = _number(int, lambda x: x >= 1, "an integer >= 1")


def add_io_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--calib", required=True, help="calibration file or folder (any supported format)"
    )
    parser.add_argument(
        "--keypoints",
        required=True,
        nargs="+",
        help="2D keypoints: rmpl .npz/.json, COCO JSON per view, OpenPose JSON folders, "
        "or a Shelf 4D folder",
    )
    parser.add_argument(
        "--skeleton", default=None, help="2D joint set when ambiguous (body25, body25b, coco18)"
    )
    parser.add_argument("--out", required=True, help=f"output file: {', '.join(OUTPUT_SUFFIXES)}")
    parser.add_argument(
        "--fps", type=positive, default=None, help="frame rate for TRC/C3D if the input has none"
    )


def axis_vector(name: str | None) -> np.ndarray | None:
    """``--up``: ``"-y"`` -> (0, -1, 0); None stays None."""
    if name is None:
        return None
    v = np.zeros(3)
    v["xyz".index(name[-1])] = -1.0 if name.startswith("-") else 1.0
    return v


def check_output(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in OUTPUT_SUFFIXES:
        raise InputError(
            path, None, f"an output file ending in one of {', '.join(OUTPUT_SUFFIXES)}"
        )
    return path


def load_calibration_and_2d(args: argparse.Namespace, cache: Path | None = None):
    """The command's calibration and 2D input (:func:`rmpl.pipeline.inputs.load_inputs`)."""
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    return load_inputs(InputSpec.from_args(args), cache)


def _source(args: argparse.Namespace) -> str:
    return ", ".join(args.keypoints) if getattr(args, "keypoints", None) else "2D input"


def check_estimated(poses, args: argparse.Namespace, method: str) -> None:
    """A result with no joint at all is an error (exit 2), not an empty file."""
    if np.isfinite(poses.points).any():
        return
    why = (
        "no frame in which two views see the same joint" if method != "rmpl"
        else "no frame with a keypoint"
    )  # fmt: skip
    raise InputError(_source(args), None, "2D input from which some joint can be estimated",
                     f"nothing estimated ({why})")  # fmt: skip


def check_cameras(rig: Rig, calib: str, method: str) -> None:
    if method != "rmpl" and len(rig) < 2:
        raise InputError(calib, "cameras", "at least 2 cameras to triangulate", len(rig))


def log_joint_sets(joints_2d: str, joints_3d: str) -> None:
    """Say which joint set the 2D came in and which one the 3D is written in."""
    from rmpl.skeleton import SKELETONS

    s = SKELETONS[joints_3d]
    extra = [n for n in s.joints if n not in SKELETONS[joints_2d].joints]
    log.info(
        "joints: 2D %s, 3D %s (%d joints%s)", joints_2d, s.name, s.num_joints,
        f"; estimated without 2D: {', '.join(extra)}" if extra else "",
    )  # fmt: skip


def run_single_method(args: argparse.Namespace, method: str, **config) -> int:
    """``rmpl lift`` / ``rmpl triangulate``: per-frame estimates, associated and tracked,
    without temporal smoothing, written to one file."""
    from rmpl.io.poses import save_poses
    from rmpl.models import choose_model
    from rmpl.pipeline.job import estimate_poses
    from rmpl.pipeline.runner import RunConfig

    out = check_output(args.out)
    inputs = load_calibration_and_2d(args)
    check_cameras(inputs.rig, args.calib, method)
    auto_model = config.get("model", "") is None
    if auto_model:  # rmpl lift without --model: per frame
        config["model"] = choose_model(len(inputs.rig), inputs.fps, method, whole_tracks=False)
    cfg = RunConfig(method=method, **config)
    spec = getattr(args, "floor", None)
    poses, _, _ = estimate_poses(inputs, cfg, spec, temporal=False, auto_model=auto_model)
    check_estimated(poses, args, method)
    log_joint_sets(inputs.skeleton, poses.skeleton)
    if out.suffix.lower() in (".trc", ".c3d") and not poses.fps:
        raise InputError(out, "fps", "a frame rate for TRC/C3D (the input has none: pass --fps)")
    save_poses(poses, out)
    ok = np.isfinite(poses.points).all(-1)
    log.info(
        "wrote %s: %d frames x %d people, %.0f%% of joints present",
        out,
        ok.shape[0],
        ok.shape[1],
        100 * ok.mean(),
    )
    return 0
