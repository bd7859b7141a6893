"""The MoveNet detectors through the video/image path (rmpl.pipeline.detect2d): the registry,
a tiny image folder and a tiny video of rendered people, a view with nobody, nobody at all.

Needs OpenCV; the detectors need ai-edge-litert and mediapipe; the rendered people moderngl
(EGL) and anny (tests.conftest.synth_ready).
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.pipeline import detect2d
from rmpl.pipeline.detect2d import DEFAULT_DETECTOR, DETECTORS

cv2 = pytest.importorskip("cv2")


def test_registry_names_every_detector_and_the_old_one_stays():
    for name in ("movenet", "movenet-blazepose", "movenet-blazepose-static",
                 "blazepose-multi", "blazepose-multi-static", "mediapipe"):  # fmt: skip
        assert name in DETECTORS
    assert DEFAULT_DETECTOR in DETECTORS
    with pytest.raises(ValueError, match="detector must be one of"):
        detect2d._make_detector("no-such-detector")
    # The default keeps the feet: HALPE-26 output.
    assert DEFAULT_DETECTOR in ("movenet-blazepose", "blazepose-multi")


@pytest.mark.parametrize("name, cls", [("movenet", "MoveNet"),
                                       ("movenet-blazepose", "MoveNetBlazePose")])  # fmt: skip
def test_registry_builds_the_named_detector(name, cls):
    pytest.importorskip("ai_edge_litert")
    pytest.importorskip("mediapipe")
    det, owned = detect2d._make_detector(name)
    try:
        assert owned and type(det).__name__ == cls and det.name == name
    finally:
        det.close()


@pytest.fixture(scope="module")
def scene():
    """Two rendered people in two frames, (T, 360, 640, 3), and their COCO-17 projections."""
    pytest.importorskip("ai_edge_litert")
    pytest.importorskip("mediapipe")
    from tests.synth.test_detect_multi import _two_bodies

    return _two_bodies(frames=2)


def _folder(path, images):
    path.mkdir()
    for i, im in enumerate(images):
        cv2.imwrite(str(path / f"frame{i}.png"), cv2.cvtColor(im, cv2.COLOR_RGB2BGR))
    return path


def test_images_with_people_and_a_view_with_nobody(tmp_path, scene, caplog):
    from tests.synth.test_detect_multi import _match

    images, truth = scene
    people = _folder(tmp_path / "cam0", images)
    empty = _folder(tmp_path / "cam1", [np.full_like(im, 80) for im in images])
    with caplog.at_level(logging.WARNING, logger="rmpl.pipeline.detect2d"):
        kp = detect2d.detect_images([people, empty], "movenet-blazepose", progress=False)
    assert kp.skeleton == "halpe26" and kp.views == ["cam0", "cam1"]
    assert kp.keypoints.shape[:2] == (2, 2) and kp.keypoints.shape[2] >= 2
    found = (kp.scores > 0).any(-1)  # (T, V, P)
    assert (found[:, 0].sum(-1) == 2).all() and not found[:, 1].any()
    for t in range(2):
        assert (_match(kp.keypoints[t, 0], truth[t]) < 15).all()
    assert any("cam1" in r.getMessage() and "nobody" in r.getMessage() for r in caplog.records)


def test_video_through_movenet_alone_is_coco17(tmp_path, scene):
    from tests.pipeline.test_detect2d import write_video

    images, _ = scene
    video = write_video(tmp_path / "c0.mp4", list(images), fps=25)
    kp = detect2d.detect_videos([video], "movenet", progress=False)
    assert kp.skeleton == "coco17" and kp.fps == pytest.approx(25)
    assert ((kp.scores[:, 0] > 0).any(-1).sum(-1) == 2).all()


def test_nobody_anywhere_is_an_input_error(tmp_path):
    pytest.importorskip("ai_edge_litert")
    pytest.importorskip("mediapipe")
    blank = [np.full((96, 128, 3), 80, np.uint8)] * 2
    folders = [_folder(tmp_path / f"cam{v}", blank) for v in range(2)]
    with pytest.raises(InputError, match="nobody in any frame"):
        detect2d.detect_images(folders, "movenet-blazepose", progress=False)


def test_views_in_parallel_on_ray_equal_one_after_the_other(tmp_path, scene):
    pytest.importorskip("ray")
    import ray

    images, _ = scene
    folders = [_folder(tmp_path / "cam0", images), _folder(tmp_path / "cam1", images[::-1])]
    serial = detect2d.detect_images(folders, "movenet", progress=False)
    started = ray.is_initialized()
    try:
        parallel = detect2d.detect_images(folders, "movenet", progress=False, workers=2)
    finally:
        if not started:
            ray.shutdown()
    np.testing.assert_array_equal(parallel.keypoints, serial.keypoints)
    np.testing.assert_array_equal(parallel.scores, serial.scores)
    with pytest.raises(ValueError, match="detector name"):
        detect2d.detect_images(folders, object(), progress=False, workers=2)
