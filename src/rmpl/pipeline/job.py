"""One run's 3D from its inputs, as ``rmpl run`` and ``rmpl lift`` do it.

:func:`estimate_poses` takes the read inputs (:func:`rmpl.pipeline.inputs.load_inputs`), a
:class:`rmpl.pipeline.runner.RunConfig` and the ``--floor`` text, and takes one of two
paths: one camera with a per-frame model (or a temporal one that reads the floor) goes to
:func:`rmpl.pipeline.monocular.lift_single_view`, depth from the floor, body size and time;
everything else to :func:`rmpl.pipeline.runner.run_with_floor`. Without ``--model`` the
model is :func:`rmpl.models.choose_model`'s.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.models import checkpoint_reads_floor, choose_model, is_temporal_checkpoint

__all__ = [
    "estimate_poses",
    "lift_one_camera",
    "multi_view_floor",
    "one_camera",
    "resolve_floor",
]

log = logging.getLogger(__name__)


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
        return check_floor(_floor_of_poses_file(spec, up), rig.centers, "--floor", spec)
    if Path(spec).suffix.lower() in (".npz", ".json", ".trc", ".c3d"):
        raise InputError(spec, "--floor", "an existing poses file of a multi-view run", "none")
    return check_floor(parse_floor(spec), rig.centers)


def _floor_of_poses_file(path: str, up):
    """The floor under the people of a poses file (``--floor poses.npz``)."""
    from rmpl.io.poses import load_poses
    from rmpl.pipeline.depth_cues import floor_from_poses
    from rmpl.skeleton import convert

    poses = load_poses(path)
    pts = poses.points
    if poses.skeleton != "coco17":
        pts = convert(pts, poses.skeleton, "coco17")
    try:
        return floor_from_poses(pts, up)
    except InputError as e:
        raise InputError(path, "points", e.expected, e.got) from None


def one_camera(rig: Rig, method: str, model: str) -> bool:
    """Whether a run takes the single-view path (:mod:`rmpl.pipeline.monocular`): one
    camera, learned lifting with a per-frame model or a temporal one that reads the floor."""
    if len(rig) != 1 or method != "rmpl":
        return False
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


def _warn_unused_floor(spec: str | None, used, cfg) -> None:
    """A ``--floor`` given to triangulation is said, not silently dropped (a model that
    does not read it is said by :func:`rmpl.pipeline.runner.run`)."""
    given = spec is not None and spec.strip().lower() != "none"
    if given and used is None and cfg.method != "rmpl":
        log.warning("--floor is not used: --method %s does not read the floor", cfg.method)


def lift_one_camera(inputs, cfg, floor_spec: str | None, temporal: bool, auto_model=False):
    """One camera: the lifter, depth from the floor, body size and time
    (:func:`rmpl.pipeline.monocular.lift_single_view`). With ``auto_model`` (no ``--model``
    given) the model is :func:`rmpl.models.choose_model`'s once the floor is known.

    Returns:
        (poses, the floor: a :class:`rmpl.geometry.floor.Floor` or None)."""
    from rmpl.pipeline.monocular import lift_single_view
    from rmpl.pipeline.runner import check_run_cutoff

    up = None if cfg.up is None else np.asarray(cfg.up, float)
    floor = resolve_floor(floor_spec, inputs.rig, up)
    if auto_model:
        model = choose_model(1, inputs.fps, cfg.method, temporal, floor is not None)
        if model != cfg.model:
            log.info("no floor: lifting with --model %s and the body-size prior", model)
            cfg = replace(cfg, model=model)
    check_run_cutoff(cfg, inputs.fps, temporal)
    poses = lift_single_view(
        inputs.keypoints, inputs.scores, inputs.rig, inputs.frames, inputs.fps, floor, cfg,
        temporal=temporal, joints=inputs.skeleton,
    )  # fmt: skip
    return poses, floor


def estimate_poses(inputs, cfg, floor_spec: str | None, temporal=True, auto_model=False):
    """A run's 3D: one camera (:func:`lift_one_camera`) or several
    (:func:`rmpl.pipeline.runner.run_with_floor`, the floor from :func:`multi_view_floor`).

    Args:
        inputs: :class:`rmpl.pipeline.inputs.Inputs`.
        cfg: the :class:`rmpl.pipeline.runner.RunConfig` (its model already chosen).
        floor_spec: ``--floor``.
        temporal: ``rmpl run`` (filters, whole tracks) or ``rmpl lift`` (False).
        auto_model: no ``--model`` was given (one camera: chosen again once the floor is
            known).

    Returns:
        (poses, the floor the lifter was given or None, whether it took one camera's path).
    """
    from rmpl.pipeline.runner import run_with_floor

    single = one_camera(inputs.rig, cfg.method, cfg.model)
    if temporal and len(inputs.rig) == 1 and cfg.method == "rmpl" and not single:
        log.warning(
            "ONE CAMERA with the temporal model: nothing fixes the depth along the rays "
            "(expect errors of 0.3 m or more); --model floor26 reads the floor (with none, the "
            "default one-camera path uses body size and time)"
        )
    if single:  # depth from the floor, body size and time (it says so in the log)
        poses, floor = lift_one_camera(inputs, cfg, floor_spec, temporal, auto_model)
        return poses, floor, True
    up = None if cfg.up is None else np.asarray(cfg.up, float)
    poses, floor = run_with_floor(
        inputs.keypoints, inputs.scores, inputs.rig, inputs.frames, inputs.fps, cfg,
        temporal=temporal, joints=inputs.skeleton,
        floor=multi_view_floor(floor_spec, inputs.rig, up),
    )  # fmt: skip
    _warn_unused_floor(floor_spec, floor, cfg)
    return poses, floor, False
