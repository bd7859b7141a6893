"""Tests for the MHP render core: random cameras (pure numpy, always run), the OpenGL
renderer (needs moderngl + EGL) and anny bodies (needs anny and a built cache, found through
ANNY_CACHE_DIR, else built on first use in ~/.cache/rmpl/anny: see tests.conftest.synth_ready)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rmpl.geometry.camera import camera_centers, project
from rmpl.synth.cameras import (
    _COMMON_SIZES,
    CAMERA_PRESETS,
    CameraPreset,
    horizontal_fov_to_focal,
    sample_cameras,
)
from rmpl.synth.render import gl_projection, random_background, random_outfits, vertex_normals
from tests.conftest import synth_ready

# ---------------------------------------------------------------- cameras (pure numpy)

PRESETS = sorted(CAMERA_PRESETS)


@pytest.mark.parametrize("preset", PRESETS)
def test_cameras_see_the_person(preset):
    rng = np.random.default_rng(0)
    centers = np.c_[rng.uniform(-1, 1, (50, 2)), rng.uniform(0.8, 1.1, 50)]  # (50, 3)
    K, R, t, size = sample_cameras(20, centers, preset, rng)
    assert K.shape == (50, 20, 3, 3) and R.shape == (50, 20, 3, 3)
    assert t.shape == (50, 20, 3) and size.shape == (50, 20, 2)
    uv = project(centers[:, None], K, R, t)  # (50, 20, 2)
    margin = CAMERA_PRESETS[preset].margin
    assert np.all(uv >= margin * size - 1e-9) and np.all(uv <= (1 - margin) * size + 1e-9)
    # In front of the camera and far enough.
    C = camera_centers(R, t)
    assert np.all(np.einsum("bvj,bvj->bv", R[..., 2, :], centers[:, None] - C) > 0)
    dist = np.linalg.norm(C - centers[:, None], axis=-1)
    assert dist.min() >= CAMERA_PRESETS[preset].min_distance


@pytest.mark.parametrize("preset", PRESETS)
def test_cameras_are_upright_rotations(preset):
    K, R, t, size = sample_cameras(500, [0.2, -0.3, 1.0], preset, rng=1)
    assert np.allclose(R @ np.swapaxes(R, -1, -2), np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(R), 1.0)
    roll = np.degrees(np.arcsin(np.abs(R[:, 0, 2])))  # tilt of the image x axis
    assert roll.max() <= CAMERA_PRESETS[preset].roll + 1e-6
    assert np.all(R[:, 1, 2] < 0)  # image "down" points down in the world
    assert np.all(K[:, 0, 1] == 0) and np.allclose(K[:, 2], [0, 0, 1])


def test_h36m_ranges():
    K, R, t, size = sample_cameras(2000, [0.0, 0.5, 1.0], "h36m", rng=2)
    C = camera_centers(R, t)
    assert np.all(np.abs(C[:, 0]) <= 2.2) and np.all(np.abs(C[:, 1]) <= 5.2)
    assert np.all((C[:, 2] >= 1) & (C[:, 2] <= 2))
    assert np.all(size == [1000, 1000])
    assert np.all((K[:, 0, 0] >= 1140) & (K[:, 0, 0] <= 1150)) and np.all(K[:, 0, 0] == K[:, 1, 1])
    assert np.all(np.abs(K[:, :2, 2] - 500) <= 15)


@pytest.mark.parametrize(
    ("preset", "sizes", "focal"),
    [("panoptic", [(1920, 1080)], (1400, 1700)), ("shelf", [(1032, 776)], (1050, 1150))],
)
def test_orbit_ranges(preset, sizes, focal):
    p = CAMERA_PRESETS[preset]
    center = np.array([0.5, -0.5, 0.9])
    K, R, t, size = sample_cameras(2000, center, preset, rng=3)
    C = camera_centers(R, t)
    horizontal = np.linalg.norm(C[:, :2] - center[:2], axis=-1)
    assert horizontal.min() >= p.distance[0] and horizontal.max() <= p.distance[1]
    assert C[:, 2].min() >= p.height[0] and C[:, 2].max() <= p.height[1]
    assert {tuple(s) for s in size.tolist()} == set(sizes)
    assert K[:, 0, 0].min() >= focal[0] and K[:, 0, 0].max() <= focal[1]
    # Cameras all around the person.
    azimuth = np.arctan2(C[:, 1] - center[1], C[:, 0] - center[0])
    assert np.histogram(azimuth, bins=8, range=(-np.pi, np.pi))[0].min() > 100


def test_universal_ranges():
    K, R, t, size = sample_cameras(3000, [0.0, 0.0, 1.0], "universal", rng=4)
    fov = 2 * np.degrees(np.arctan(size[:, 0] / 2 / K[:, 0, 0]))
    assert fov.min() >= 35 - 1e-6 and fov.max() <= 90 + 1e-6
    assert {tuple(s) for s in size.tolist()} <= set(_COMMON_SIZES)
    assert len({tuple(s) for s in size.tolist()}) > 5
    C = camera_centers(R, t)
    horizontal = np.linalg.norm(C[:, :2], axis=-1)
    assert horizontal.min() >= 1.5 - 1e-9 and horizontal.max() <= 8 + 1e-9
    assert horizontal.max() > 7 and horizontal.min() < 2.5  # the range is used


def test_cameras_reproducible():
    a = sample_cameras(5, np.zeros((3, 3)) + [0, 0, 1], "universal", rng=7)
    b = sample_cameras(5, np.zeros((3, 3)) + [0, 0, 1], "universal", rng=np.random.default_rng(7))
    c = sample_cameras(5, np.zeros((3, 3)) + [0, 0, 1], "universal", rng=8)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.allclose(a[2], c[2])


def test_cameras_bad_input():
    with pytest.raises(ValueError, match="unknown camera preset"):
        sample_cameras(2, [0, 0, 1], "kinect")
    with pytest.raises(ValueError, match="person_center"):
        sample_cameras(2, [0, 1], "h36m")
    with pytest.raises(ValueError, match="num"):
        sample_cameras(0, [0, 0, 1], "h36m")
    with pytest.raises(ValueError, match="focal and fov"):
        CameraPreset("x", "orbit", distance=(1, 2), height=(1, 2))
    impossible = CameraPreset(
        "x", "orbit", distance=(1, 2), height=(1, 2), focal=(500, 500), min_distance=50.0
    )
    with pytest.raises(RuntimeError, match="no valid camera"):
        sample_cameras(2, [0, 0, 1], impossible, rng=0, max_tries=3)


def test_horizontal_fov_to_focal():
    f = horizontal_fov_to_focal(np.array([60.0]), np.array([1920]))
    assert np.allclose(2 * np.degrees(np.arctan(960 / f)), 60.0)


# ---------------------------------------------------------------- render helpers (numpy)


def test_gl_projection_matches_project():
    rng = np.random.default_rng(0)
    K, R, t, size = sample_cameras(10, [0, 0, 1], "universal", rng)
    X = rng.normal([0, 0, 1], 0.5, (10, 3))
    for v in range(10):
        uv = project(X, K[v], R[v], t[v])
        M = gl_projection(K[v], R[v], t[v], tuple(size[v]))
        clip = np.c_[X, np.ones(10)] @ M.T
        ndc = clip[:, :3] / clip[:, 3:]
        window = (ndc[:, :2] + 1) / 2 * size[v]
        np.testing.assert_allclose(window - 0.5, uv, atol=1e-6)
        assert np.all(np.abs(ndc[:, 2]) < 1)  # inside the depth range


def _box(center, half):
    """A closed axis-aligned box: vertices (8, 3), outward counter-clockwise faces (12, 3)."""
    s = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [f for a, b, c, d in quads for f in ((a, b, c), (a, c, d))]
    return np.asarray(center) + s * half, np.array(faces)


def test_vertex_normals_point_outward():
    v, f = _box([1.0, 2.0, 3.0], [0.5, 1.0, 2.0])
    n = vertex_normals(v[None], f)[0]
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1, atol=1e-6)
    assert np.all(np.einsum("nj,nj->n", n, v - [1.0, 2.0, 3.0]) > 0)


def test_random_outfits_and_background():
    from rmpl.synth.body import PARTS

    parts = np.arange(len(PARTS)).repeat(3)
    c = random_outfits(parts, 4, rng=0)
    assert c.shape == (4, len(parts), 3) and c.dtype == np.float32
    assert c.min() >= 0 and c.max() <= 1
    face, hand = PARTS.index("face"), PARTS.index("hand")
    # Face and hands share the skin colour (up to the per-vertex mottling).
    assert np.allclose(c[:, parts == face].mean(1), c[:, parts == hand].mean(1), rtol=0.1)
    bg = random_background(64, 48, rng=1)
    assert bg.shape == (48, 64, 3) and bg.dtype == np.uint8 and bg.std() > 0
    np.testing.assert_array_equal(bg, random_background(64, 48, rng=1))


# ---------------------------------------------------------------- renderer (moderngl + EGL)


@pytest.fixture(scope="module")
def box_renderer():
    pytest.importorskip("moderngl")
    from rmpl.synth.render import Renderer

    v, f = _box([0.0, 0.0, 1.0], [0.3, 0.2, 0.5])
    try:
        r = Renderer(f, len(v))
    except Exception as e:  # no EGL driver on this machine
        pytest.skip(f"no headless OpenGL context: {e}")
    yield r, v
    r.close()


def test_render_pinhole_matches_project(box_renderer):
    """The silhouette of a box is the set of pixel centres inside its projected outline."""
    r, v = box_renderer
    K = np.array([[[[700.0, 0, 300.3], [0, 650, 170.6], [0, 0, 1]]]])
    from rmpl.geometry.camera import look_at

    R, t = look_at(np.array([0.4, -3.0, 1.6]), np.array([0.1, 0.0, 0.9]))
    R, t = R[None, None], t[None, None]
    size = np.array([[[640, 360]]])  # non-square, off-centre principal point
    colors = np.full((1, len(v), 3), 0.8, np.float32)
    images, masks = r.render(v[None], colors, K, R, t, size, backgrounds=False, return_masks=True)
    mask = masks[0]
    assert images[0].shape == (360, 640, 3) and mask.shape == (360, 640)
    # Expected silhouette: pixels whose centre lies inside the convex hull of the projected box.
    uv = project(v, K[0, 0], R[0, 0], t[0, 0])
    from scipy.spatial import ConvexHull, Delaunay

    hull = Delaunay(uv[ConvexHull(uv).vertices])
    jj, ii = np.mgrid[0:360, 0:640]
    expected = hull.find_simplex(np.c_[ii.ravel(), jj.ravel()]) >= 0
    expected = expected.reshape(360, 640)
    disagree = mask != expected
    assert expected.sum() > 5000
    # Only pixels whose centre is within a pixel of the outline may disagree.
    assert disagree.sum() < 0.02 * expected.sum()
    ys, xs = np.nonzero(mask)
    ye, xe = np.nonzero(expected)
    for got, want in (
        (xs.min(), xe.min()),
        (xs.max(), xe.max()),
        (ys.min(), ye.min()),
        (ys.max(), ye.max()),
    ):
        assert abs(got - want) <= 1
    # A half-pixel or row/column flip would show here.
    np.testing.assert_allclose([xs.mean(), ys.mean()], [xe.mean(), ye.mean()], atol=0.1)
    assert images[0][mask].mean() > 30 and images[0][~mask].max() == 0  # black backdrop


def test_render_batch_backgrounds_and_sizes(box_renderer):
    r, v = box_renderer
    K, R, t, size = sample_cameras(
        3, np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]), "universal", rng=5
    )
    verts = np.stack([v, v])
    colors = random_outfits(np.zeros(len(v), int), 2, rng=0)
    images, masks = r.render(verts, colors, K, R, t, size, rng=0, return_masks=True)
    assert len(images) == 6 and len(masks) == 6
    for i, (im, m) in enumerate(zip(images, masks, strict=True)):
        w, h = size.reshape(-1, 2)[i]
        assert im.shape == (h, w, 3) and im.dtype == np.uint8
        assert 0 < m.mean() < 1
        assert im[~m].std() > 0  # a backdrop, not a flat clear colour
    again = r.render(verts, colors, K, R, t, size, rng=0)
    for a, b in zip(images, again, strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="vertices"):
        r.render(verts[:, :3], colors, K, R, t, size)
    with pytest.raises(ValueError, match="size"):
        r.render(verts, colors, K, R, t, size[:, :2])


# ---------------------------------------------------------------- anny bodies


def anny_cache() -> Path:
    """anny's cache (built on first use), else skip when anny is missing."""
    return synth_ready("anny")


@pytest.fixture(scope="module")
def body_model():
    from rmpl.synth.body import BodyModel

    return BodyModel(cache_dir=anny_cache())


def test_body_rest_pose_axes_and_units(body_model):
    from rmpl.skeleton import COCO17
    from rmpl.synth.body import PARTS, PHENOTYPES

    m = body_model
    assert m.num_bones == len(m.bone_names) == 104 and "upperarm01.L" in m.bone_names
    assert m.faces.shape[1] == 3 and m.faces.max() < m.num_vertices
    assert m.vertex_parts.shape == (m.num_vertices,)
    assert set(np.unique(m.vertex_parts)) == set(range(len(PARTS)))
    b = m(m.identity_pose(1), np.full((1, len(PHENOTYPES)), 0.5))
    k = b.keypoints[0]
    assert b.vertices.shape == (1, m.num_vertices, 3) and k.shape == (17, 3)
    i = COCO17.index
    height = np.ptp(b.vertices[0, :, 2])
    assert 1.5 < height < 2.0  # metres, z up
    assert k[i("nose"), 2] > k[i("left_hip"), 2] > k[i("left_ankle"), 2]
    assert k[i("nose"), 1] < k[i("left_ear"), 1]  # faces -y
    assert k[i("left_shoulder"), 0] > k[i("right_shoulder"), 0]  # left is +x


def test_body_random_poses_keep_bone_lengths(body_model):
    from rmpl.skeleton import COCO17
    from rmpl.synth.body import place_bodies, sample_phenotypes

    m = body_model
    ph = sample_phenotypes(6, rng=0)
    rest = m(m.identity_pose(6), ph)
    posed = m(m.sample_poses(6, rng=0), ph)
    assert np.isfinite(posed.vertices).all()
    assert not np.allclose(rest.keypoints, posed.keypoints, atol=0.05)
    bones = np.array(COCO17.bones[:12])  # limbs and hips/shoulders

    def lengths(k):
        return np.linalg.norm(k[:, bones[:, 0]] - k[:, bones[:, 1]], axis=-1)

    np.testing.assert_allclose(lengths(posed.keypoints), lengths(rest.keypoints), rtol=0.15)
    v, k = place_bodies(posed.vertices, posed.keypoints, np.full(6, 0.3), np.ones((6, 2)))
    np.testing.assert_allclose(v[..., 2].min(1), 0, atol=1e-5)
    np.testing.assert_allclose(k[:, 11:13].mean(1)[:, :2], 1, atol=1e-5)
    with pytest.raises(ValueError, match="pose"):
        m(np.zeros((2, 5, 4, 4)), ph[:2])
    with pytest.raises(ValueError, match="phenotypes"):
        m(m.identity_pose(2), ph[:3])


def test_keypoints_land_on_the_rendered_body(body_model):
    """Projected regressed keypoints fall on the silhouette: rendering and rmpl's project agree."""
    pytest.importorskip("moderngl")
    from rmpl.synth.body import place_bodies, sample_phenotypes
    from rmpl.synth.render import Renderer

    m, rng = body_model, np.random.default_rng(0)
    b = m(m.sample_poses(3, rng), sample_phenotypes(3, rng))
    v, k = place_bodies(b.vertices, b.keypoints, rng.uniform(0, 2 * np.pi, 3), np.zeros((3, 2)))
    K, R, t, size = sample_cameras(4, k[:, 11:13].mean(1), "h36m", rng)
    try:
        r = Renderer(m.faces, m.num_vertices)
    except Exception as e:
        pytest.skip(f"no headless OpenGL context: {e}")
    with r:
        colors = random_outfits(m.vertex_parts, 3, rng)
        _, masks = r.render(v, colors, K, R, t, size, rng=rng, return_masks=True)
    uv = project(k[:, None], K[:, :, None], R[:, :, None], t[:, :, None]).reshape(12, 17, 2)
    hits = total = 0
    for mask, p in zip(masks, uv, strict=True):
        ij = np.round(p).astype(int)
        ok = (ij >= 0).all(-1) & (ij < mask.shape[::-1]).all(-1)
        hits += mask[ij[ok, 1], ij[ok, 0]].sum()
        total += ok.sum()
    assert total > 150 and hits / total > 0.95
