"""Camera geometry: cameras and rigs, projection, rays, triangulation."""

from rmpl.geometry.camera import (
    Camera,
    Rig,
    distort,
    look_at,
    project,
    rodrigues,
    rotation_to_rodrigues,
    undistort,
    undistort_points,
)
from rmpl.geometry.rays import closest_point_to_rays, rays_from_keypoints
from rmpl.geometry.triangulate import (
    TriangulationResult,
    recenter_point,
    reprojection_error,
    triangulate,
    triangulate_robust,
)

__all__ = [
    "Camera",
    "Rig",
    "TriangulationResult",
    "closest_point_to_rays",
    "distort",
    "look_at",
    "project",
    "rays_from_keypoints",
    "recenter_point",
    "reprojection_error",
    "rodrigues",
    "rotation_to_rodrigues",
    "triangulate",
    "triangulate_robust",
    "undistort",
    "undistort_points",
]
