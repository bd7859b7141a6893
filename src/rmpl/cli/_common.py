"""What the 3D commands share: read calibration + 2D input, match views to cameras."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig

#: ``--model`` help of the commands that lift (the names of rmpl.inference.PRETRAINED, kept
#: here so that building the parser does not import torch).
MODEL_HELP = (
    "shipped model (floor26: per frame, COCO-17 + head top, neck, mid-hip and feet, reads the "
    "floor (--floor); halpe26: the same without the floor; scenes26: halpe26 also "
    "trained on multi-person scenes; default: per frame, COCO-17; "
    "occlusion: COCO-17, for many missing keypoints; temporal26 / temporal: whole tracks, "
    "HALPE-26 / COCO-17, need a frame rate) or checkpoint folder"
)

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


def resolve_floor(spec: str | None, rig: Rig, up):
    """The floor of a run's ``--floor`` (:mod:`rmpl.geometry.floor`), checked against the
    rig (with two or more cameras, None is "estimate" instead: :func:`multi_view_floor`).

    The floor must be right to a few centimetres: with a camera at height h looking at
    ankles at distance D, a floor error e moves the person by about e D / h along the rays.

    Args:
        spec: ``--floor``: None (the calibration's convention, if it has one), "none", a
            plane (:func:`rmpl.geometry.floor.parse_floor`) or an existing poses file of a
            multi-view run of the same rig.
        up: ``--up`` as a vector, or None.

    Returns:
        A :class:`rmpl.geometry.floor.Floor`, or None (no floor: size prior and time only).

    Raises:
        InputError: a floor that is not a plane or that lies above the camera(s).
    """
    from rmpl.geometry.floor import check_floor, convention_floor, parse_floor

    if spec is not None and spec.strip().lower() == "none":
        return None
    if spec is None:
        floor = convention_floor(rig.R, rig.centers, up)
        if floor is None:
            log.warning(
                "one camera and no floor known (the calibration has no axis-aligned up with "
                "the cameras upright and above 0): depth from body size and time only; give "
                "--floor"
            )
        return floor
    if Path(spec).is_file():
        from rmpl.io.poses import load_poses
        from rmpl.pipeline.monocular import floor_from_poses
        from rmpl.skeleton import convert

        poses = load_poses(spec)
        pts = poses.points
        if poses.skeleton != "coco17":
            pts = convert(pts, poses.skeleton, "coco17")
        try:
            floor = floor_from_poses(pts, up)
        except InputError as e:
            raise InputError(spec, "points", e.expected, e.got) from None
        return check_floor(floor, rig.centers, "--floor", spec)
    if Path(spec).suffix.lower() in (".npz", ".json", ".trc", ".c3d"):
        raise InputError(spec, "--floor", "an existing poses file of a multi-view run", "none")
    return check_floor(parse_floor(spec), rig.centers)


def log_joint_sets(joints_2d: str, joints_3d: str) -> None:
    """Say which joint set the 2D came in and which one the 3D is written in."""
    from rmpl.skeleton import SKELETONS

    s = SKELETONS[joints_3d]
    extra = [n for n in s.joints if n not in SKELETONS[joints_2d].joints]
    log.info(
        "joints: 2D %s, 3D %s (%d joints%s)", joints_2d, s.name, s.num_joints,
        f"; estimated without 2D: {', '.join(extra)}" if extra else "",
    )  # fmt: skip


def one_camera(rig: Rig, method: str, model: str) -> bool:
    """Whether a run takes the single-view path (:mod:`rmpl.pipeline.monocular`): one
    camera, learned lifting with a per-frame model or a temporal one that reads the floor."""
    if len(rig) != 1 or method != "rmpl":
        return False
    from rmpl.inference import checkpoint_reads_floor
    from rmpl.inference_temporal import is_temporal_checkpoint

    return not is_temporal_checkpoint(model) or checkpoint_reads_floor(model)


def multi_view_floor(spec: str | None, rig: Rig, up):
    """``--floor`` of a run with two or more cameras, for
    :func:`rmpl.pipeline.runner.run_with_floor`: "estimate" when not given (from the run's
    own triangulated people), None for "none", else the checked plane
    (:func:`resolve_floor`)."""
    from rmpl.pipeline.runner import ESTIMATE

    if spec is None:
        return ESTIMATE
    return resolve_floor(spec, rig, up)


def warn_unused_floor(spec: str | None, used, cfg) -> None:
    """A ``--floor`` given to triangulation is said, not silently dropped (a model that
    does not read it is said by :func:`rmpl.pipeline.runner.run`)."""
    given = spec is not None and spec.strip().lower() != "none"
    if given and used is None and cfg.method != "rmpl":
        log.warning("--floor is not used: --method %s does not read the floor", cfg.method)


def run_one_camera(inputs, cfg, floor_spec: str | None, temporal: bool, auto_model: bool = False):
    """``rmpl run`` / ``rmpl lift`` with one camera: the lifter, depth from the floor, body
    size and time (:func:`rmpl.pipeline.monocular.lift_single_view`). With ``auto_model``
    (no ``--model`` given) and no floor known, the model is ``rmpl.cli.run.ONE_CAMERA_NO_FLOOR``
    (the floor model was chosen with the floor given; docs/results.md); with a floor, a frame
    rate and whole tracks (``temporal``), ``rmpl.cli.run.ONE_CAMERA_TEMPORAL`` when set.

    Returns:
        (poses, the floor: a :class:`rmpl.geometry.floor.Floor` or None)."""
    from dataclasses import replace

    from rmpl.cli.run import ONE_CAMERA_NO_FLOOR, ONE_CAMERA_TEMPORAL
    from rmpl.pipeline.monocular import lift_single_view

    up = None if cfg.up is None else np.asarray(cfg.up, float)
    floor = resolve_floor(floor_spec, inputs.rig, up)
    if auto_model and floor is None:
        log.info("no floor: lifting with --model %s and the body-size prior", ONE_CAMERA_NO_FLOOR)
        cfg = replace(cfg, model=ONE_CAMERA_NO_FLOOR)
    elif auto_model and temporal and inputs.fps is not None and ONE_CAMERA_TEMPORAL:
        cfg = replace(cfg, model=ONE_CAMERA_TEMPORAL)
    from rmpl.pipeline.runner import check_run_cutoff

    check_run_cutoff(cfg, inputs.fps, temporal)
    poses = lift_single_view(
        inputs.keypoints, inputs.scores, inputs.rig, inputs.frames, inputs.fps, floor, cfg,
        temporal=temporal, joints=inputs.skeleton,
    )  # fmt: skip
    return poses, floor


def run_single_method(args: argparse.Namespace, method: str, **config) -> int:
    """``rmpl lift`` / ``rmpl triangulate``: per-frame estimates, associated and tracked,
    without temporal smoothing, written to one file."""
    from rmpl.io.poses import save_poses
    from rmpl.pipeline.runner import RunConfig, run_with_floor

    out = check_output(args.out)
    inputs = load_calibration_and_2d(args)
    check_cameras(inputs.rig, args.calib, method)
    auto_model = config.get("model", "") is None
    if auto_model:  # rmpl lift without --model: rmpl run's per-frame rule
        from rmpl.cli.run import per_frame_model

        config["model"] = per_frame_model(len(inputs.rig))
    cfg = RunConfig(method=method, **config)
    spec = getattr(args, "floor", None)
    if one_camera(inputs.rig, method, cfg.model):
        poses, _ = run_one_camera(inputs, cfg, spec, temporal=False, auto_model=auto_model)
    else:
        up = None if cfg.up is None else np.asarray(cfg.up, float)
        poses, used = run_with_floor(
            inputs.keypoints, inputs.scores, inputs.rig, inputs.frames, inputs.fps, cfg,
            temporal=False, joints=inputs.skeleton,
            floor=multi_view_floor(spec, inputs.rig, up),
        )  # fmt: skip
        warn_unused_floor(spec, used, cfg)
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
