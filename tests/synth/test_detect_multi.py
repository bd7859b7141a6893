"""Tests for the multi-person BlazePose detector (rmpl.synth.detect_multi).

The math (anchors, decoding, suppression, crops, windows) is plain numpy. The detector
tests need ``mediapipe==0.10.14`` (its networks are in the wheel); the one on rendered
bodies also needs moderngl (EGL) and anny (tests.conftest.synth_ready), the one on the
Pose2Sim demo videos ../shared/data.
"""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.skeleton import COCO17
from rmpl.synth.detect import Detector, MultiPersonDetector, max_people, with_people_axis
from rmpl.synth.detect_multi import (
    box_iou,
    crop_affine,
    decode_detections,
    detector_windows,
    roi_from_points,
    ssd_anchors,
    weighted_nms,
)
from tests.conftest import synth_ready

# ---------------------------------------------------------------- pure numpy


def test_anchors_cover_the_input_in_three_grids():
    a = ssd_anchors()
    assert a.shape == (2254, 2)
    assert (a > 0).all() and (a < 1).all()
    # 28 x 28 cells with 2 anchors, 14 x 14 with 2, 7 x 7 with 6 (three stride-32 layers).
    assert len(np.unique(a[: 28 * 28 * 2, 0])) == 28
    assert len(np.unique(a[28 * 28 * 2 : 28 * 28 * 2 + 14 * 14 * 2, 0])) == 14
    np.testing.assert_allclose(a[-1], [13 / 14, 13 / 14])  # the last 7 x 7 cell's centre


def test_decode_detections_offsets_from_anchors():
    anchors = np.array([[0.25, 0.5], [0.75, 0.5], [0.5, 0.5]])
    raw = np.zeros((3, 12))
    raw[1, :4] = [22.4, -22.4, 44.8, 67.2]  # +0.1, -0.1 and size 0.2 x 0.3 of 224 pixels
    raw[1, 4:6] = [0.0, 11.2]  # the first keypoint 0.05 below the anchor
    logits = np.array([5.0, 2.0, -3.0])  # sigmoid 0.993, 0.881, 0.047
    boxes, kps, scores = decode_detections(raw, logits, anchors, min_score=0.5)
    assert len(scores) == 2
    np.testing.assert_allclose(boxes[1], [0.85, 0.4, 0.2, 0.3])
    np.testing.assert_allclose(kps[1, 0], [0.75, 0.55])
    np.testing.assert_allclose(kps[0], np.tile([0.25, 0.5], (4, 1)))
    np.testing.assert_allclose(scores, 1 / (1 + np.exp(-np.array([5.0, 2.0]))))


def test_weighted_nms_merges_overlaps_and_keeps_separate_people():
    boxes = np.array([[0.3, 0.5, 0.2, 0.2], [0.32, 0.5, 0.2, 0.2], [0.7, 0.5, 0.2, 0.2]])
    kps = np.stack([np.full((4, 2), 0.3), np.full((4, 2), 0.32), np.full((4, 2), 0.7)])
    scores = np.array([0.6, 0.9, 0.8])
    b, k, s = weighted_nms(boxes, kps, scores, iou_threshold=0.3)
    assert len(s) == 2
    np.testing.assert_allclose(s, [0.9, 0.8])  # the best score of each group, best first
    w = np.array([0.9, 0.6]) / 1.5
    np.testing.assert_allclose(b[0, 0], w @ [0.32, 0.3])  # score-weighted mean
    np.testing.assert_allclose(k[1], 0.7)
    assert weighted_nms(boxes[:0], kps[:0], scores[:0])[2].shape == (0,)
    np.testing.assert_allclose(box_iou(boxes[0], boxes[2:]), [0.0])


@pytest.mark.parametrize("direction, angle", [((0, -1), 0.0), ((1, 0), np.pi / 2),
                                              ((-1, 0), -np.pi / 2), ((0, 1), -np.pi)])  # fmt: skip
def test_roi_turns_the_body_axis_upright(direction, angle):
    centre = np.array([100.0, 200.0])
    c, side, a = roi_from_points(centre, centre + 40 * np.array(direction, float))
    assert side == pytest.approx(2 * 1.25 * 40)
    assert a == pytest.approx(angle)
    # The crop's "up" (towards its top edge) is the direction from centre to scale point.
    M = crop_affine(c, side, a, 256)
    up = (M[:, :2] @ [128.0, 0.0] + M[:, 2]) - c
    np.testing.assert_allclose(up / np.linalg.norm(up), direction, atol=1e-12)


def test_detector_windows_tile_long_images():
    assert detector_windows(480, 640) == [(0, 0, 640, 480)] + [
        (0, 0, 480, 480),
        (160, 0, 640, 480),
    ]
    w = detector_windows(1920, 1088)
    assert w[0] == (0, 0, 1088, 1920)
    assert all(x1 - x0 == y1 - y0 == 1088 for x0, y0, x1, y1 in w[1:])
    assert w[1][1] == 0 and w[-1][3] == 1920  # they reach both ends


def test_people_axis_for_single_and_multi_person_detectors():
    class One:
        name, skeleton = "one", COCO17

    class Many(One):
        name, max_people = "many", 3

    kp, sc = with_people_axis(One(), np.zeros((2, 17, 2)), np.ones((2, 17)), 2)
    assert kp.shape == (2, 1, 17, 2) and sc.shape == (2, 1, 17) and max_people(One()) == 1
    kp, sc = with_people_axis(Many(), np.zeros((2, 3, 17, 2)), np.ones((2, 3, 17)), 2)
    assert kp.shape == (2, 3, 17, 2) and max_people(Many()) == 3
    with pytest.raises(ValueError, match=r"'many' returned keypoints \(2, 4, 17, 2\)"):
        with_people_axis(Many(), np.zeros((2, 4, 17, 2)), np.ones((2, 4, 17)), 2)
    with pytest.raises(ValueError, match="'one'"):
        with_people_axis(One(), np.zeros((3, 17, 2)), np.ones((3, 17)), 2)


# ---------------------------------------------------------------- the detector


@pytest.fixture(scope="module")
def blazepose():
    pytest.importorskip("mediapipe")
    from rmpl.synth.detect_multi import BlazePoseMulti

    with BlazePoseMulti(max_people=3) as det:
        yield det


def test_nobody_in_blank_images(blazepose):
    det = blazepose
    assert isinstance(det, Detector) and isinstance(det, MultiPersonDetector)
    det.reset()
    kp, sc = det([np.full((120, 160, 3), 90, np.uint8), np.zeros((200, 100, 3), np.uint8)])
    J = det.skeleton.num_joints  # HALPE-26: COCO-17 + BlazePose's heels and foot index
    assert kp.shape == (2, 3, J, 2) and sc.shape == (2, 3, J)
    assert np.isnan(kp).all() and (sc == 0).all()


def _two_bodies(frames: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Two rendered anny bodies side by side in one image, stepping sideways over
    ``frames`` frames: images (T, 360, 640, 3) and their COCO-17 projections (T, 2, 17, 2)."""
    from rmpl.geometry.camera import look_at, project
    from rmpl.synth.body import BodyModel, place_bodies
    from rmpl.synth.render import Renderer, random_lighting, random_outfits

    m = BodyModel(cache_dir=synth_ready("anny", "moderngl"))
    b = m(m.identity_pose(2), np.full((2, 6), 0.5))
    images, truth = [], []
    for t in range(frames):
        where = np.array([[-0.05 * t, 0.0], [0.05 * t, 0.3]])
        v, k = place_bodies(b.vertices, b.keypoints, np.array([0.0, 0.5]), where)
        center = k[0, 11:13].mean(0)
        R, tv = look_at(center + [0.0, -4.0, 0.2], center)
        K = np.array([[420.0, 0, 159.5], [0, 420, 179.5], [0, 0, 1]])
        args = (K[None, None].repeat(2, 0), R[None, None].repeat(2, 0))
        args += (tv[None, None].repeat(2, 0), np.array([[[320, 360]]]).repeat(2, 0))
        with Renderer(m.faces, m.num_vertices) as r:
            pics = r.render(v, random_outfits(m.vertex_parts, 2, rng=1), *args,
                            lighting=[random_lighting(1)] * 2, rng=1)  # fmt: skip
        images.append(np.concatenate(pics, axis=1))  # (360, 640, 3): body 0 left, 1 right
        gt = project(k, K, R, tv)  # (2, 17, 2)
        truth.append(gt + [[[0.0, 0.0]], [[320.0, 0.0]]])
    return np.stack(images), np.stack(truth)


def _match(kp: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Median pixel error of each true person (P,) against its nearest detection."""
    kp = kp[..., : truth.shape[-2], :]  # the COCO-17 joints
    err = np.nanmedian(np.linalg.norm(kp[:, None] - truth[None], axis=-1), axis=-1)  # (N, P)
    return np.nanmin(np.where(np.isfinite(err), err, np.inf), axis=0)


def test_finds_two_rendered_people_and_keeps_their_slots(blazepose):
    images, truth = _two_bodies()
    det = blazepose
    det.reset()
    kp, sc = det(images)
    found = (sc > 0).any(-1)  # (T, N)
    assert (found.sum(1) == 2).all(), found
    for t in range(len(images)):
        assert (_match(kp[t], truth[t]) < 15).all()  # px; each person ~250 px tall
    # Followed people keep their slots: slot n is the same person in every frame.
    left = kp[:, :, 11:13, 0].mean(-1) < 320  # (T, N) hips on the left half
    used = found[0]
    assert found[:, used].all() and (left[:, used] == left[0, used]).all()
    assert left[0, used].sum() == 1  # one on each side
    # Every image afresh (track=False) finds the same people.
    from rmpl.synth.detect_multi import BlazePoseMulti

    with BlazePoseMulti(max_people=3, track=False) as static:
        kp2, sc2 = static(images[:1])
    assert (sc2[0] > 0).any(-1).sum() == 2
    assert (_match(kp2[0], truth[0]) < 15).all()


@pytest.mark.shared
def test_both_participants_of_the_pose2sim_multi_person_demo(shared_data, blazepose):
    cv2 = pytest.importorskip("cv2")
    video = shared_data / "pose2sim_videos" / "Demo_MultiPerson" / "videos" / "cam01.mp4"
    if not video.is_file():
        pytest.skip(f"{video} not found")
    cap = cv2.VideoCapture(str(video))
    frames = [cv2.cvtColor(cap.read()[1], cv2.COLOR_BGR2RGB) for _ in range(6)]
    cap.release()
    blazepose.reset()
    kp, sc = blazepose(frames)
    people = ((sc > 0.5).sum(-1) >= 8).sum(-1)  # per frame, people with 8+ confident joints
    assert (people[1:] == 2).all(), people
