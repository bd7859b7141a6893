"""rmpl: the Ray-based Multi-view 2D-to-3D Pose Lifter.

Two lines to a 3D skeleton::

    rig, kp = rmpl.load_rig("calib.toml"), rmpl.load_keypoints("keypoints.json")
    poses = rmpl.Lifter.from_pretrained().lift(kp.keypoints, kp.scores, rig)
"""

from __future__ import annotations

from rmpl.geometry import (
    Camera,
    Rig,
    TriangulationResult,
    project,
    rays_from_keypoints,
    recenter_point,
    triangulate,
    triangulate_robust,
    undistort_points,
)
from rmpl.inference import Lifter, LiftResult
from rmpl.io.calibration import load_rig, save_rig
from rmpl.io.keypoints import Keypoints2D, load_keypoints
from rmpl.io.poses import Poses3D, load_poses, save_poses
from rmpl.metrics import mpjpe, pa_mpjpe, pck, pcp
from rmpl.model import RMPL, RMPLConfig
from rmpl.skeleton import COCO17, H36M17, SHELF14, SKELETONS, Skeleton

__version__ = "0.1.0"

__all__ = [
    "COCO17",
    "H36M17",
    "SHELF14",
    "SKELETONS",
    "RMPL",
    "Camera",
    "Keypoints2D",
    "LiftResult",
    "Lifter",
    "Poses3D",
    "RMPLConfig",
    "Rig",
    "Skeleton",
    "TriangulationResult",
    "__version__",
    "load_keypoints",
    "load_poses",
    "load_rig",
    "mpjpe",
    "pa_mpjpe",
    "pck",
    "pcp",
    "project",
    "rays_from_keypoints",
    "save_poses",
    "save_rig",
    "recenter_point",
    "triangulate",
    "triangulate_robust",
    "undistort_points",
]
