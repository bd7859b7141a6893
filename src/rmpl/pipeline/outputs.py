"""The files of a run folder: exports, the run report, the viewer, pictures and overlays,
changing as one set.

:func:`write_all` checks the views and builds the run report
(:func:`rmpl.pipeline.report.build_report`: each person's height and the per-view status go
into the poses), writes every requested export of the :class:`rmpl.io.poses.Poses3D` (NPZ,
JSON, TRC, C3D, BVH), ``report.md`` and ``report.json``, the viewer page, the pictures and
the overlays into a staging folder and commits them together
(:func:`rmpl.io.atomic.staged_folder`); ``rmpl run`` and ``rmpl example`` call it. It
returns the :class:`~rmpl.pipeline.report.RunReport`, whose ``exit_code`` is the command's
status: 0, or 3 when a person's views disagree in most frames (a blend of different people;
the outputs are still written, :mod:`rmpl.pipeline.consistency`).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

__all__ = ["FORMATS", "pose2sim_min_frames_of", "write_all", "write_input_overlays"]

log = logging.getLogger(__name__)

FORMATS = ("npz", "json", "trc", "c3d", "bvh")


def write_input_overlays(sources: list[str], kind: str, poses, inputs, out: Path) -> list[Path]:
    """The result drawn onto the input ``kind`` ("videos" or "images" folders) ``sources``,
    one overlay per camera."""
    from rmpl.pipeline.detect2d import view_names
    from rmpl.pipeline.overlay import write_overlays

    names = view_names(sources)
    if set(names) == set(inputs.rig.names):  # the same matching as load_calibration_and_2d
        sources = [sources[names.index(n)] for n in inputs.rig.names]
    return write_overlays(
        sources,
        poses,
        inputs.rig,
        out,
        keypoints=inputs.keypoints,
        scores=inputs.scores,
        frames=inputs.frames,
        kind=kind,
    )


def _write_bvh(poses, out: Path) -> None:
    """BVH holds one skeleton: poses.bvh for one person, else poses_p<id>.bvh each."""
    from rmpl.errors import InputError
    from rmpl.io.poses import save_poses

    for p, pid in enumerate(poses.person_ids.tolist()):
        one = poses.person(p)
        name = "poses.bvh" if poses.num_people == 1 else f"poses_p{pid}.bvh"
        try:
            save_poses(one, out / name)
        except InputError as e:  # a person too briefly seen for a skeleton
            log.warning("skipping %s: %s", name, e)


def write_all(
    poses,
    inputs,
    out: Path,
    formats: list[str],
    pictures: bool = True,
    overlays=None,
    pose2sim: str | None = "pose2sim-y-up",
    up=None,
    floor="not recorded",
    pose2sim_min_frames: int | None = None,
):
    """The run report, every requested export plus the viewer page, the pictures and
    ``overlays(folder)``, committed into ``out`` as one set
    (:func:`rmpl.io.atomic.staged_folder`): after a failure or a kill, ``out`` holds the
    previous complete set or this one, never a mix.

    The exports carry each person's height and the view check's per-view status
    (:func:`rmpl.pipeline.report.build_report`). With ``pose2sim`` (an orientation of
    :func:`rmpl.io.pose2sim.write_pose2sim`; None: off) and a frame rate, ``out/pose-3d/``
    gets one TRC and one C3D per person for Pose2Sim's kinematics (OpenSim scaling + IK; its
    COCO_17 or HALPE_26 markers, by the poses' joint set), in
    a world turned so that its up axis (``up``, (3,), else estimated from the cameras) is +z.
    A summary is logged after the commit; a person whose views disagree in most frames gets
    a WARNING banner. ``floor``: the floor the lifter was given (a
    :class:`rmpl.geometry.floor.Floor`, or None: none), written to the report; by default
    not recorded (:data:`rmpl.pipeline.report.NOT_RECORDED`). ``pose2sim_min_frames``: a
    person present in fewer frames gets no Pose2Sim files of its own (it stays in the other
    exports); None: one second of frames (:func:`pose2sim_min_frames_of`).

    Returns:
        The :class:`rmpl.pipeline.report.RunReport`; its ``exit_code`` (0 or 3) is what
        ``rmpl run`` should return.
    """
    from rmpl.io.atomic import staged_folder
    from rmpl.pipeline.report import build_report, log_summary, write_report

    report = build_report(poses, inputs, floor=floor)
    poses = report.poses
    with staged_folder(out) as stage:
        _export(poses, stage, formats)
        if pose2sim is not None:
            least = pose2sim_min_frames_of(poses.fps, pose2sim_min_frames)
            _export_pose2sim(poses, stage, pose2sim, inputs.rig, up, least)
        write_report(report, stage)
        ok = np.isfinite(poses.points).all(-1)
        if pictures:
            _pictures(poses, inputs, stage, ok)
        if overlays is not None:
            overlays(stage)
    log.info(
        "%d frames, %d people, %.0f%% of joints present; wrote %s",
        len(poses.points),
        poses.points.shape[1],
        100 * ok.mean(),
        out,
    )
    if pose2sim is not None and (out / "pose-3d").is_dir():
        from rmpl.io.pose2sim import POSE_MODELS

        model = POSE_MODELS[poses.skeleton].name if poses.skeleton in POSE_MODELS else "?"
        log.info(
            "Pose2Sim trial files (one TRC + C3D per person; Pose2Sim's pose_model %s): %s",
            model, out / "pose-3d",
        )  # fmt: skip
    log_summary(report, out)
    if pictures:
        log.info("open %s in a browser to see the result", out / "viewer.html")
    return report


def _export(poses, out: Path, formats: list[str]) -> None:
    from rmpl.io.poses import save_poses

    for fmt in formats:
        if fmt in ("trc", "c3d", "bvh") and not poses.fps:
            log.warning("skipping %s: no frame rate (give --fps)", fmt.upper())
            continue
        if fmt == "bvh":
            _write_bvh(poses, out)
            continue
        save_poses(poses, out / f"poses.{fmt}")


def z_up_world(points: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (..., 3) turned so that ``up`` is +z, and that rotation (None: none needed).

    An ``up`` within 30 degrees of a world axis is taken as that axis exactly (calibrations
    state their up along an axis; the estimate from the cameras is a little off).

    >>> p, R = z_up_world(np.array([[0.0, -1.7, 0.2]]), np.array([0.05, -0.99, 0.0]))
    >>> np.round(p, 6).tolist(), R is not None
    ([[0.0, 0.2, 1.7]], True)
    >>> z_up_world(np.zeros((1, 3)), np.array([0.0, 0.1, 1.0]))[1] is None
    True
    """
    from rmpl.inference import rotation_to_z

    up = np.asarray(up, float) / np.linalg.norm(up)
    k = int(np.argmax(np.abs(up)))
    axis = np.zeros(3)
    axis[k] = np.sign(up[k])
    if axis @ up > np.cos(np.radians(30)):
        up = axis
    if np.allclose(up, [0.0, 0.0, 1.0]):
        return points, None
    R = rotation_to_z(up)
    return points @ R.T, R


def pose2sim_min_frames_of(fps: float | None, given: int | None = None) -> int:
    """The fewest frames for a person's own Pose2Sim files: ``given``, else one second
    (a gait cycle lasts about one; OpenSim's scaling and IK say little about less).

    >>> pose2sim_min_frames_of(25.0), pose2sim_min_frames_of(60.0, 10), pose2sim_min_frames_of(None)
    (25, 10, 1)
    """
    if given is not None:
        return int(given)
    return max(1, int(np.ceil(fps))) if fps else 1


def _export_pose2sim(poses, out: Path, orientation: str, rig, up, min_frames: int = 1) -> None:
    """Per-person Pose2Sim files in ``out/pose-3d/``, in a Z-up world (Pose2Sim's axes assume
    one); a run they cannot describe (no frame rate, nobody with every IK marker in some
    frame) is said, not fatal."""
    import dataclasses

    from rmpl.errors import InputError
    from rmpl.inference import estimate_up
    from rmpl.io.pose2sim import write_pose2sim

    if not poses.fps:
        log.warning("skipping the Pose2Sim files (pose-3d/): no frame rate (give --fps)")
        return
    points, R = z_up_world(poses.points, estimate_up(rig) if up is None else up)
    if R is not None:
        log.info("the world's up is not +z: the Pose2Sim files are turned to put it along +z")
        poses = dataclasses.replace(poses, points=points)
    try:
        write_pose2sim(poses, out / "pose-3d", stem="poses", orientation=orientation,
                       min_frames=min_frames)  # fmt: skip
    except InputError as e:
        log.warning("skipping the Pose2Sim files (pose-3d/): %s", e)


def _pictures(poses, inputs, out: Path, ok: np.ndarray) -> None:
    from rmpl.skeleton import SKELETONS
    from rmpl.viz.plots import plot_reprojection, plot_skeletons
    from rmpl.viz.viewer import write_viewer

    skeleton = SKELETONS[poses.skeleton]  # the bones of the poses' joint set (feet too)
    write_viewer(poses, out / "viewer.html", cameras=inputs.rig)
    plot_skeletons(poses.points, out / "skeleton.png", rig=inputs.rig, skeleton=skeleton)
    busiest = int(np.argmax(ok.sum((1, 2)))) if ok.any() else 0
    person = int(np.argmax(ok[busiest].sum(-1))) if ok.any() else 0
    kp, sc = inputs.keypoints[:, :, 0], inputs.scores[:, :, 0]
    if inputs.keypoints.shape[2] == 1:
        plot_reprojection(
            kp, sc, poses.points[:, person], inputs.rig, out / "reprojection.png", frame=busiest,
            skeleton=skeleton,
        )  # fmt: skip
