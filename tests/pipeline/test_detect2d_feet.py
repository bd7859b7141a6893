"""Video detections keep a detector's feet: BlazePose-33 -> HALPE-26; the 2D cache names its
joint set, and an old COCO-17 cache still loads."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, load_keypoints, save_keypoints
from rmpl.skeleton import BLAZEPOSE33, COCO17, HALPE26

cv2 = pytest.importorskip("cv2")

from rmpl.pipeline import detect2d  # noqa: E402  (after the importorskip)
from tests.pipeline.test_detect2d import CountingDetector, _frames, _rig, write_video  # noqa: E402


class FakeBlazePose:
    """A stand-in BlazePose: 33 landmarks, landmark ``j`` of image ``i`` at (j, brightness),
    scores 0.5 + j / 100."""

    name = "fake-blazepose"
    skeleton = BLAZEPOSE33

    def __call__(self, images):
        B, J = len(images), BLAZEPOSE33.num_joints
        kp = np.zeros((B, J, 2))
        kp[..., 0] = np.arange(J) + 1.0
        kp[..., 1] = np.array([im.mean() for im in images])[:, None] + 1.0
        return kp, np.broadcast_to(0.5 + np.arange(J) / 100, (B, J)).copy()

    def close(self) -> None:
        pass


def _videos(tmp_path, n=2, frames=3):
    return [str(write_video(tmp_path / f"cam{v}.mp4", _frames(frames, v))) for v in range(n)]


def test_blazepose33_detector_gives_heels_and_foot_index(tmp_path):
    kp = detect2d.detect_videos(_videos(tmp_path), FakeBlazePose(), progress=False)
    assert kp.skeleton == "halpe26" and kp.keypoints.shape == (3, 2, 1, 26, 2)
    x, sc = kp.keypoints[..., 0], kp.scores  # x = BlazePose landmark index + 1
    for name in COCO17.joints + ("left_heel", "right_heel"):
        j = BLAZEPOSE33.index(name)
        assert (x[..., HALPE26.index(name)] == j + 1).all(), name
        np.testing.assert_allclose(sc[..., HALPE26.index(name)], 0.5 + j / 100)
    for side in ("left", "right"):
        big_toe = HALPE26.index(f"{side}_big_toe")
        assert (x[..., big_toe] == BLAZEPOSE33.index(f"{side}_foot_index") + 1).all()
    for name in ("head_top", "neck", "mid_hip", "left_small_toe", "right_small_toe"):
        j = HALPE26.index(name)
        assert np.isnan(kp.keypoints[..., j, :]).all() and (sc[..., j] == 0).all(), name


def test_coco17_detector_stays_coco17(tmp_path):
    kp = detect2d.detect_videos(_videos(tmp_path), CountingDetector(), progress=False)
    assert kp.skeleton == "coco17" and kp.keypoints.shape[-2] == 17


def test_cache_records_halpe26_and_an_old_coco17_cache_loads(tmp_path, monkeypatch):
    from rmpl.pipeline.inputs import InputSpec, _load_2d, load_inputs

    det = FakeBlazePose()
    monkeypatch.setitem(detect2d.DETECTORS, "fake-blazepose", lambda: det)
    save_rig(_rig(2), tmp_path / "calib.toml")
    spec = InputSpec(
        calib=str(tmp_path / "calib.toml"), videos=_videos(tmp_path), detector="fake-blazepose"
    )
    cache = tmp_path / "out" / "keypoints2d.npz"
    first = _load_2d(spec, cache)
    assert first.skeleton == "halpe26"
    assert load_keypoints(cache, to=None).skeleton == "halpe26"  # the file names its set
    inputs = load_inputs(spec, cache)
    assert inputs.skeleton == "halpe26" and inputs.keypoints.shape[-2] == 26

    # A cache written before the feet were kept: COCO-17, same inputs stamp. Still used.
    old = Keypoints2D(
        first.keypoints[..., :17, :], first.scores[..., :17], "coco17", first.views,
        first.frames, first.fps,
    )  # fmt: skip
    save_keypoints(old, cache)
    again = load_inputs(spec, cache)
    assert again.skeleton == "coco17"
    np.testing.assert_array_equal(again.keypoints, first.keypoints[..., :17, :])


def test_a_coco17_view_cache_beside_halpe26_views(tmp_path, caplog):
    """Resuming: a view saved in COCO-17 is placed in HALPE-26 beside freshly detected ones,
    with a warning that says how to get its feet."""
    videos = _videos(tmp_path)
    resume = tmp_path / "resume"
    full = detect2d.detect_videos(videos, FakeBlazePose(), cache_dir=resume, progress=False)
    view0 = next(resume.glob("00_*.npz"))
    with np.load(view0) as data:
        stamp, kp, sc = str(data["stamp"]), data["keypoints"], data["scores"]
    detect2d._save_view(view0, stamp, kp[..., :17, :], sc[..., :17])  # an old view file
    (next(resume.glob("01_*.npz"))).unlink()
    with caplog.at_level("WARNING"):
        mixed = detect2d.detect_videos(videos, FakeBlazePose(), cache_dir=resume, progress=False)
    assert "reusing COCO-17 detections" in caplog.text and "delete it" in caplog.text
    assert mixed.skeleton == "halpe26"
    np.testing.assert_array_equal(mixed.keypoints[:, 1], full.keypoints[:, 1])
    np.testing.assert_array_equal(mixed.keypoints[:, 0, :, :17], full.keypoints[:, 0, :, :17])
    assert np.isnan(mixed.keypoints[:, 0, :, 17:]).all() and (mixed.scores[:, 0, :, 17:] == 0).all()


def test_stamp_unchanged_for_a_cache(tmp_path):
    """The inputs stamp does not name the joint set, so caches made before still match."""
    from rmpl.pipeline.inputs import InputSpec, _check_detection_inputs

    save_rig(_rig(2), tmp_path / "calib.toml")
    spec = InputSpec(calib=str(tmp_path / "calib.toml"), videos=_videos(tmp_path))
    stamp = _check_detection_inputs(spec, "videos", spec.videos, "blazepose-multi")
    assert sorted(stamp) == ["detector", "fps", "inputs", "kind"]
