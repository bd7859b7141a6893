import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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

finite = st.floats(-1, 1, allow_nan=False)


def random_rig(rng, num=4, dist_scale=0.0):
    cams = []
    for i in range(num):
        ang = rng.uniform(0, 2 * np.pi)
        eye = np.array([4 * np.cos(ang), 4 * np.sin(ang), rng.uniform(0.5, 3)])
        R, t = look_at(eye, rng.uniform(-0.3, 0.3, 3) + [0, 0, 1])
        f = rng.uniform(400, 1500)
        K = np.array(
            [[f, 0, rng.uniform(300, 700)], [0, f * rng.uniform(0.95, 1.05), 400], [0, 0, 1]]
        )
        dist = dist_scale * np.array([-0.2, 0.05, 1e-3, -1e-3, 0.01]) * rng.uniform(0, 1, 5)
        cams.append(Camera(K, R, t, dist, (1000, 800), f"c{i}"))
    return Rig(tuple(cams))


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 10_000))
def test_undistort_inverts_distort(seed):
    rng = np.random.default_rng(seed)
    d = np.array([-0.3, 0.1, 2e-3, -2e-3, -0.02]) * rng.uniform(0, 1, 5)
    xy = rng.uniform(-0.5, 0.5, (20, 2))
    assert np.allclose(undistort(distort(xy, d), d), xy, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000))
def test_rodrigues_round_trip(seed):
    rng = np.random.default_rng(seed)
    r = rng.uniform(-1, 1, 3) * rng.uniform(0, 3)
    R = rodrigues(r)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.allclose(rodrigues(rotation_to_rodrigues(R)), R, atol=1e-9)
    assert np.linalg.norm(rotation_to_rodrigues(R)) <= np.pi + 1e-9


def test_project_known_value_and_centre():
    K = np.array([[100.0, 0, 50], [0, 200, 40], [0, 0, 1]])
    cam = Camera(K, np.eye(3), np.array([0.0, 0.0, 2.0]))
    assert np.allclose(cam.center, [0, 0, -2])
    assert np.allclose(cam.project(np.array([0.2, 0.4, 0.0])), [60.0, 80.0])
    # Behind the camera: NaN, never a wrapped-around pixel.
    assert np.isnan(cam.project(np.array([0.0, 0.0, -3.0]))).all()


def test_undistort_points_matches_projection():
    rng = np.random.default_rng(0)
    rig = random_rig(rng, 3, dist_scale=1.0)
    X = rng.uniform(-0.5, 0.5, (50, 3)) + [0, 0, 1]
    for cam in rig:
        distorted = cam.project(X)
        ideal = project(X, cam.K, cam.R, cam.t)
        assert np.allclose(undistort_points(distorted, cam.K, cam.dist), ideal, atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000))
def test_project_rays_closest_point_recovers_points(seed):
    rng = np.random.default_rng(seed)
    rig = random_rig(rng, int(rng.integers(2, 6)), dist_scale=1.0)
    X = rng.uniform(-0.6, 0.6, (17, 3)) + [0, 0, 1]
    kp = rig.project(X)  # (V, J, 2)
    rays = rays_from_keypoints(kp, rig)
    assert rays.shape == (len(rig), 17, 6)
    assert np.allclose(np.linalg.norm(rays[..., 3:], axis=-1), 1)
    assert np.allclose(rays[..., :3], rig.centers[:, None])
    assert np.allclose(closest_point_to_rays(rays), X, atol=1e-6)


def test_rays_batched_over_leading_dims():
    rng = np.random.default_rng(1)
    rig = random_rig(rng, 3)
    X = rng.uniform(-0.5, 0.5, (4, 5, 17, 3)) + [0, 0, 1]
    kp = rig.project(X)  # (4, 5, V, J, 2)
    rays = rays_from_keypoints(kp, rig)
    assert rays.shape == (4, 5, 3, 17, 6)
    assert np.allclose(closest_point_to_rays(rays), X, atol=1e-6)


def test_bad_camera_inputs_are_clear():
    K = np.eye(3)
    with pytest.raises(ValueError, match="rotation"):
        Camera(K, np.diag([1.0, 1, -1]), np.zeros(3))
    with pytest.raises(ValueError, match=r"K must have shape \(3, 3\)"):
        Camera(np.eye(2), np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        Camera(K, np.eye(3), np.array([0, np.nan, 0]))
    with pytest.raises(ValueError, match="distortion"):
        Camera(K, np.eye(3), np.zeros(3), dist=np.zeros(7))
    with pytest.raises(ValueError, match="views"):
        rays_from_keypoints(np.zeros((2, 17, 2)), random_rig(np.random.default_rng(0), 3))
