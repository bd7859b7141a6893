"""Tests for the MHP detector adapters, and the MHP render + detect benchmark.

The MediaPipe tests need ``mediapipe==0.10.14``; the ones on rendered bodies also need
moderngl (EGL) and anny (its cache: $ANNY_CACHE_DIR or built on first use). The benchmark
only runs when asked:

    python -m pytest tests/synth/test_detect.py -m benchmark -s

It prints per-stage costs and the detector's error against the projected regressed
keypoints, and writes example images and ``report.json`` to $RMPL_MHP_EXAMPLES
(default /tmp/mhp_examples).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from rmpl.geometry.camera import look_at, project
from rmpl.skeleton import COCO17, HALPE26
from rmpl.synth.detect import DETECTORS, Detector, MediaPipeDetector, as_image_list, zero_outside
from tests.conftest import synth_ready

# ---------------------------------------------------------------- pure numpy


def test_zero_outside_batched():
    kp = np.array([[[0.0, 0.0], [99.4, 49.4], [99.6, 10.0], [10.0, -0.6], [np.nan, 1.0]]] * 2)
    scores = np.full((2, 5), 0.9)
    size = np.array([[100, 50], [200, 50]])
    out = zero_outside(kp, scores, size)
    np.testing.assert_array_equal(out[0], [0.9, 0.9, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(out[1], [0.9, 0.9, 0.9, 0.0, 0.0])


def test_as_image_list_validates():
    assert len(as_image_list(np.zeros((2, 4, 5, 3), np.uint8))) == 2
    mixed = [np.zeros((4, 5, 3), np.uint8), np.zeros((6, 7, 3), np.uint8)]
    assert [im.shape for im in as_image_list(mixed)] == [(4, 5, 3), (6, 7, 3)]
    with pytest.raises(ValueError, match=r"\(B, H, W, 3\)"):
        as_image_list(np.zeros((4, 5, 3), np.uint8))
    with pytest.raises(ValueError, match="image 1"):
        as_image_list([np.zeros((4, 5, 3), np.uint8), np.zeros((4, 5, 3), np.float32)])


def test_registry():
    assert DETECTORS["mediapipe"] is MediaPipeDetector


# ---------------------------------------------------------------- MediaPipe


@pytest.fixture(scope="module")
def mediapipe_detector():
    pytest.importorskip("mediapipe")
    with MediaPipeDetector() as det:
        yield det


def test_mediapipe_misses_are_nan(mediapipe_detector):
    det = mediapipe_detector
    assert isinstance(det, Detector) and det.skeleton is HALPE26
    images = [np.full((120, 160, 3), 90, np.uint8), np.zeros((100, 100, 3), np.uint8)]
    kp, scores = det(images)
    assert kp.shape == (2, 26, 2) and scores.shape == (2, 26)
    assert np.isnan(kp).all() and (scores == 0).all()


def _anny_cache() -> Path:
    return synth_ready("anny", "moderngl")


def _front_view(k: np.ndarray, width: int = 640, height: int = 480, distance: float = 3.5):
    """A camera in front (-y) of a body with keypoints k (17, 3): K, R, t, size, (1, 1, ...)."""
    center = k[11:13].mean(0)
    R, t = look_at(center + [0.3, -distance, 0.2], center)
    K = np.array([[600.0, 0, width / 2], [0, 600, height / 2], [0, 0, 1]])
    return K[None, None], R[None, None], t[None, None], np.array([[[width, height]]])


def test_mediapipe_finds_a_rendered_body(mediapipe_detector):
    from rmpl.synth.body import BodyModel, place_bodies
    from rmpl.synth.render import Renderer, random_lighting, random_outfits

    m = BodyModel(cache_dir=_anny_cache(), joints="halpe26")
    b = m(m.identity_pose(1), np.full((1, 6), 0.5))
    v, k = place_bodies(b.vertices, b.keypoints, np.zeros(1), np.zeros((1, 2)))
    K, R, t, size = _front_view(k[0])
    with Renderer(m.faces, m.num_vertices) as r:
        images = r.render(
            v,
            random_outfits(m.vertex_parts, 1, rng=0),
            K,
            R,
            t,
            size,
            lighting=[random_lighting(0)],
            rng=0,
        )
    kp, scores = mediapipe_detector(images)
    gt = project(k[0], K[0, 0], R[0, 0], t[0, 0])
    err = np.linalg.norm(kp[0] - gt, axis=-1)
    coco = err[:17]
    assert np.isfinite(coco).all()
    assert np.median(coco) < 15  # px; the person is ~330 px tall
    assert (scores[0, :17] > 0.5).sum() >= 13
    # HALPE-26: BlazePose gives the heels and (as the big toe) the foot index, on the feet
    # of the mesh; the head top, neck, mid-hip and small toes are missing.
    feet = HALPE26.indices(["left_heel", "right_heel", "left_big_toe", "right_big_toe"])
    assert np.isfinite(err[feet]).all() and np.median(err[feet]) < 20
    absent = HALPE26.indices(["head_top", "neck", "mid_hip", "left_small_toe"])
    assert np.isnan(kp[0, absent]).all() and (scores[0, absent] == 0).all()


# ---------------------------------------------------------------- benchmark


def _draw(image: np.ndarray, points: np.ndarray, color, radius: int) -> None:
    h, w = image.shape[:2]
    for x, y in np.round(points[np.isfinite(points).all(-1)]).astype(int):
        image[
            max(y - radius, 0) : min(y + radius + 1, h), max(x - radius, 0) : min(x + radius + 1, w)
        ] = color


def _draw_skeleton(image: np.ndarray, kp: np.ndarray, color) -> None:
    for a, b in COCO17.bones:
        if np.isfinite(kp[[a, b]]).all():
            s = np.linspace(0, 1, 60)[:, None]
            _draw(image, kp[a] * (1 - s) + kp[b] * s, color, 1)


@pytest.mark.benchmark
def test_benchmark_mhp_render_detect(request):
    if "benchmark" not in (request.config.getoption("-m") or ""):
        pytest.skip("a measurement, not a test: run with -m benchmark")
    pytest.importorskip("mediapipe")
    from PIL import Image

    from rmpl.synth.body import BodyModel, place_bodies, sample_phenotypes
    from rmpl.synth.cameras import sample_cameras
    from rmpl.synth.render import Renderer, random_outfits

    out_dir = Path(os.environ.get("RMPL_MHP_EXAMPLES", "/tmp/mhp_examples"))
    out_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    report: dict[str, float | str] = {}

    t0 = time.perf_counter()
    model = BodyModel(cache_dir=_anny_cache())
    report["body_model_init_s"] = time.perf_counter() - t0

    batch, num_bodies, views = 32, 25, 4
    phen = sample_phenotypes(batch, rng)
    t0 = time.perf_counter()
    pose = model.sample_poses(batch, rng)
    report["pose_sampler_ms_per_mesh"] = (time.perf_counter() - t0) / batch * 1e3
    model(pose, phen)  # warm-up
    runs = []
    for _ in range(5):
        t0 = time.perf_counter()
        bodies = model(pose, phen)
        runs.append(time.perf_counter() - t0)
    report["body_ms_per_mesh_batch32"] = float(np.median(runs)) / batch * 1e3

    # The thesis's Human3.6M room: random yaw, x in [-1, 1], y in [-1.5, 2] m.
    yaw = rng.uniform(0, 2 * np.pi, num_bodies)
    where = np.c_[rng.uniform(-1, 1, num_bodies), rng.uniform(-1.5, 2, num_bodies)]
    v, k = place_bodies(bodies.vertices[:num_bodies], bodies.keypoints[:num_bodies], yaw, where)
    K, R, t, size = sample_cameras(views, k[:, 11:13].mean(1), "h36m", rng)
    colors = random_outfits(model.vertex_parts, num_bodies, rng)
    with Renderer(model.faces, model.num_vertices) as renderer:
        renderer.render(v[:1], colors[:1], K[:1, :1], R[:1, :1], t[:1, :1], size[:1, :1])
        t0 = time.perf_counter()
        images = renderer.render(v, colors, K, R, t, size, rng=rng)
        report["render_ms_per_view_1000x1000"] = (time.perf_counter() - t0) / len(images) * 1e3
        Ku, Ru, tu, su = sample_cameras(views, k[:, 11:13].mean(1), "universal", rng)
        t0 = time.perf_counter()
        renderer.render(v[:10], colors[:10], Ku[:10], Ru[:10], tu[:10], su[:10], rng=rng)
        report["render_ms_per_view_universal"] = (time.perf_counter() - t0) / (10 * views) * 1e3

    with MediaPipeDetector() as det:
        det(images[:1])  # warm-up
        t0 = time.perf_counter()
        kp, scores = det(images)
        report["detect_ms_per_view"] = (time.perf_counter() - t0) / len(images) * 1e3

    report["end_to_end_views_per_s"] = 1e3 / (
        report["body_ms_per_mesh_batch32"] / views
        + report["render_ms_per_view_1000x1000"]
        + report["detect_ms_per_view"]
    )
    gt = project(k[:, None], K[:, :, None], R[:, :, None], t[:, :, None])  # (B, V, 17, 2)
    gt = gt.reshape(-1, 17, 2)
    in_image = zero_outside(gt, np.ones(gt.shape[:2]), size.reshape(-1, 2)) > 0
    dist = np.where(in_image, np.linalg.norm(kp - gt, axis=-1), np.nan)  # (B * V, 17), px
    err = dist[np.isfinite(dist)]
    missed_image = np.isnan(kp).all(axis=(1, 2))
    report |= {
        "num_renders": len(images),
        "image_miss_rate": float(missed_image.mean()),
        "joint_miss_rate": float((scores[in_image] == 0).mean()),
        "joint_low_score_rate_below_0.5": float((scores[in_image] < 0.5).mean()),
        "error_px_mean": float(err.mean()),
        "error_px_median": float(np.median(err)),
        "error_px_p90": float(np.percentile(err, 90)),
        "keypoint_box_height_px_median": float(np.median(np.ptp(gt[..., 1], axis=1))),
        "per_joint_error_px_mean": {
            name: float(np.nanmean(dist[:, j])) for j, name in enumerate(COCO17.joints)
        },
    }
    for n, i in enumerate((0, views + 1, 2 * views + 2)):  # three bodies, three cameras
        im = images[i].copy()
        _draw_skeleton(im, gt[i], (0, 255, 0))  # projected regressed keypoints: green
        _draw_skeleton(im, kp[i], (255, 0, 0))  # detections: red
        _draw(im, gt[i], (0, 255, 0), 3)
        _draw(im, kp[i], (255, 0, 0), 3)
        Image.fromarray(im).save(out_dir / f"mhp_example_{n}.png")
    (out_dir / "report.json").write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))
    assert report["image_miss_rate"] < 0.5
