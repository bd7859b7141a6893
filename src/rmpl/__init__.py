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
from rmpl.skeleton import COCO17, H36M17, SHELF14, SKELETONS, Skeleton

__version__ = "0.1.0"

__all__ = [
    "COCO17",
    "H36M17",
    "SHELF14",
    "SKELETONS",
    "Camera",
    "Rig",
    "Skeleton",
    "TriangulationResult",
    "__version__",
    "project",
    "rays_from_keypoints",
    "recenter_point",
    "triangulate",
    "triangulate_robust",
    "undistort_points",
]
