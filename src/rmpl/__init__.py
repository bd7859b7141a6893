"""rmpl: the Ray-based Multi-view 2D-to-3D Pose Lifter.

A few lines to a 3D skeleton, here on the walk example shipped with rmpl (4 cameras). A
keypoint file holds (T, V, P, J, 2) pixels: P people per view, not yet associated across
views; the lifter takes one person, (T, V, J, 2), so pass person ``p`` as ``[:, :, p]``
(``rmpl run`` associates and tracks several people)::

    >>> import rmpl
    >>> from rmpl.evaluate.example import EXAMPLE
    >>> rig = rmpl.load_rig(EXAMPLE / "calibration.toml")
    >>> kp = rmpl.load_keypoints(EXAMPLE / "keypoints.json")
    >>> result = rmpl.Lifter.from_pretrained().lift(kp.keypoints[:, :, 0], kp.scores[:, :, 0], rig)
    >>> result.points.shape  # (T, J, 3): world metres per frame and joint
    (60, 17, 3)
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
