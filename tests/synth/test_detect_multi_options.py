"""BlazePoseMulti's options (nms_iou, window_scales, min_detection) and the generator's
``detector_options``.

The detector's own path (windows, decoding, suppression) runs on a stand-in for its two
networks, so these tests need neither mediapipe nor its models; the end-to-end generator
test needs anny and EGL (tests.conftest.synth_ready).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import rmpl.synth.detect_multi as dm
from rmpl.errors import InputError
from rmpl.skeleton import COCO17
from rmpl.synth.generate import GenerateConfig, _config_dict, generate, list_shards, make_detector
from tests.conftest import synth_ready

S = dm.DETECTOR_SIZE


def _person(anchor: np.ndarray, centre, side: float = 0.2, radius: float = 0.3) -> np.ndarray:
    """The detector's raw regression (12,) for a box of ``side`` at ``centre`` (normalised),
    from ``anchor``: box, then mid-hip (the centre), scale point, mid-shoulder, extra."""
    c = np.asarray(centre, float)
    points = [c, c - [0, radius], c - [0, radius / 2], c - [0, radius]]
    raw = [*(c - anchor), side, side, *np.concatenate([p - anchor for p in points])]
    return np.asarray(raw) * S


class _FakeNetwork:
    """Stands in for dm._Network: the detector returns :attr:`people` (centre, score) at
    the anchors nearest their centres; the landmark network finds nobody."""

    people: list[tuple[tuple[float, float], float]] = []

    def __init__(self, which: str) -> None:
        self.which = which

    def __call__(self, image: np.ndarray) -> list[np.ndarray]:
        if self.which == "landmarks":
            return [np.zeros(39 * 5), np.zeros(1)]  # presence 0: nobody
        anchors = dm.ssd_anchors()
        raw, logits = np.zeros((len(anchors), 12)), np.full(len(anchors), -20.0)
        for centre, score in self.people:
            a = int(np.argmin(np.linalg.norm(anchors - centre, axis=1)))
            raw[a] = _person(anchors[a], centre)
            logits[a] = np.log(score / (1 - score))
        return [raw.ravel(), logits]

    def close(self) -> None:
        pass


@pytest.fixture
def fake_networks(monkeypatch):
    monkeypatch.setattr(dm, "model_buffer", lambda which, keep_outputs=None: which)
    monkeypatch.setattr(dm, "_Network", _FakeNetwork)
    yield _FakeNetwork
    _FakeNetwork.people = []


def _box_iou(a, b) -> float:
    return float(dm.box_iou(np.array([*a, 0.2, 0.2]), np.array([[*b, 0.2, 0.2]]))[0])


# ------------------------------------------------------------------------ the detector


def test_nms_iou_keeps_overlapping_people_apart_or_merges_them(fake_networks):
    # Two people whose boxes overlap by IoU ~0.5 (neighbours in a crowded image).
    a, b = (0.40, 0.5), (0.47, 0.5)
    assert 0.3 < _box_iou(a, b) < 0.6
    fake_networks.people = [(a, 0.9), (b, 0.8)]
    image = np.zeros((S, S, 3), np.uint8)
    merged = dm.BlazePoseMulti(track=False)._detect(image, (0, 0, S, S))  # nms_iou 0.3
    apart = dm.BlazePoseMulti(track=False, nms_iou=0.6)._detect(image, (0, 0, S, S))
    assert len(merged) == 1 and len(apart) == 2
    hips = sorted(d[3][0] for d in apart)  # each keeps its own mid-hip, pixels
    np.testing.assert_allclose(hips, [a[0] * S, b[0] * S], atol=1e-6)
    # Merged: the score-weighted mean of the two.
    np.testing.assert_allclose(merged[0][3][0], (0.9 * a[0] + 0.8 * b[0]) / 1.7 * S, atol=1e-6)


def test_min_detection_drops_weak_people(fake_networks):
    fake_networks.people = [((0.3, 0.5), 0.9), ((0.7, 0.5), 0.4)]
    image = np.zeros((S, S, 3), np.uint8)
    assert len(dm.BlazePoseMulti(track=False)._detect(image, (0, 0, S, S))) == 1
    assert len(dm.BlazePoseMulti(track=False, min_detection=0.3)._detect(image, (0, 0, S, S))) == 2


@pytest.mark.parametrize("scales, runs", [((1.0,), 1), ((1.0, 0.5), 10), ([0.5], 10)])
def test_window_scales_set_where_the_detector_looks(fake_networks, scales, runs):
    det = dm.BlazePoseMulti(track=False, window_scales=scales)
    kp, sc = det([np.zeros((100, 100, 3), np.uint8)])
    assert det.calls["detector"] == runs  # the whole image, then a 3 x 3 grid of half squares
    assert kp.shape[:2] == (1, 4) and (sc == 0).all()


class _PatchDetector(_FakeNetwork):
    """A detector that sees a bright patch as a person only when the patch is at least
    30 pixels wide in its 224-pixel input (people far from the camera are small)."""

    def __call__(self, image: np.ndarray) -> list[np.ndarray]:
        if self.which == "landmarks":
            return super().__call__(image)
        ys, xs = np.nonzero(image[..., 0] > 128)
        big = len(xs) > 0 and np.ptp(xs) + 1 >= 30
        centre = ((xs.mean() + 0.5) / S, (ys.mean() + 0.5) / S) if big else None
        type(self).people = [(centre, 0.9)] if big else []
        return super().__call__(image)


def test_a_small_window_finds_a_person_the_whole_image_misses(fake_networks, monkeypatch):
    monkeypatch.setattr(dm, "_Network", _PatchDetector)
    image = np.zeros((400, 400, 3), np.uint8)
    image[50:90, 250:290] = 255  # 40 px: 22 px in the whole-image view, 45 px in a half one
    found = []
    original = dm.BlazePoseMulti._detect

    def detect(self, image, window):
        out = original(self, image, window)
        found.extend(d[3] for d in out)  # mid-hips, image pixels
        return out

    monkeypatch.setattr(dm.BlazePoseMulti, "_detect", detect)
    dm.BlazePoseMulti(track=False)([image])
    assert found == []
    dm.BlazePoseMulti(track=False, window_scales=[1.0, 0.5])([image])
    assert len(found) >= 1
    # Window pixels map back to the image: the patch's centre (continuous coordinates).
    np.testing.assert_allclose(np.mean(found, axis=0), [270.0, 70.0], atol=1.5)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"nms_iou": 0.0}, "nms_iou"),
        ({"nms_iou": 1.5}, "nms_iou"),
        ({"nms_iou": True}, "nms_iou"),
        ({"nms_iou": "0.3"}, "nms_iou"),
        ({"window_scales": [1.0, 0.0]}, "window_scales"),
        ({"window_scales": [1.2]}, "window_scales"),
        ({"window_scales": ["half"]}, "window_scales"),
        ({"window_scales": -0.5}, "window_scales"),
    ],
)
def test_bad_options_are_refused_by_name(kwargs, name):
    # Checked before any network is loaded (mediapipe is not needed to refuse them).
    with pytest.raises(ValueError, match=name):
        dm.BlazePoseMulti(**kwargs)


def test_windows_cover_the_image_at_every_scale():
    for height, width in [(1080, 1920), (1920, 1080), (480, 640), (333, 1000), (500, 500)]:
        for scale in (1.0, 0.6, 0.5, 0.25):
            windows = dm.detector_windows(height, width, (scale,))
            assert windows[0] == (0, 0, width, height)
            covered = np.zeros((height, width), bool)
            for x0, y0, x1, y1 in windows[1:] or windows:
                assert 0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height
                assert x1 - x0 == y1 - y0 or (x0, y0, x1, y1) == windows[0]  # squares
                covered[y0:y1, x0:x1] = True
            assert covered.all(), (height, width, scale)


# ------------------------------------------------------------------------ the generator


class OptionDetector:
    """A one-person detector for the generator test: every joint at the image centre with
    score ``score``."""

    name = "option-test"
    skeleton = COCO17

    def __init__(self, score: float = 0.5) -> None:
        self.score = score

    def __call__(self, images):
        images = list(images)
        centres = np.array([[im.shape[1] / 2, im.shape[0] / 2] for im in images])
        kp = np.repeat(centres[:, None], COCO17.num_joints, axis=1)
        return kp, np.full((len(images), COCO17.num_joints), self.score)


_SPEC = f"{__name__}:OptionDetector"


def test_detector_options_reach_the_constructor():
    det = make_detector(_SPEC, {"score": 0.25})
    assert det.score == 0.25
    assert make_detector(_SPEC).score == 0.5


@pytest.mark.parametrize(
    "detector, options, unknown",
    [
        ("blazepose-multi", {"nms_iu": 0.5}, "nms_iu"),  # a typo of nms_iou
        ("blazepose-multi-static", {"window_scales": [0.5], "tiles": 2}, "tiles"),
        ("mediapipe", {"max_people": 2}, "max_people"),
        (_SPEC, {"scroe": 0.1}, "scroe"),
    ],
)
def test_unknown_detector_options_name_the_field_and_the_key(detector, options, unknown):
    with pytest.raises(InputError, match=rf"'detector_options'.*{unknown}"):
        GenerateConfig.from_dict({"detector": detector, "detector_options": options}, "x.toml")
    with pytest.raises(InputError, match=unknown):
        make_detector(detector, options)


def test_detector_options_config():
    cfg = GenerateConfig.from_toml(
        _toml(), ["detector_options={ nms_iou = 0.6, window_scales = [1.0, 0.5] }"]
    )
    assert cfg.detector_options == {"nms_iou": 0.6, "window_scales": [1.0, 0.5]}
    assert _config_dict(cfg)["detector_options"] == cfg.detector_options
    # Without options the manifest's config is as before the option existed (resumable).
    assert "detector_options" not in _config_dict(GenerateConfig.from_toml(_toml()))
    with pytest.raises(InputError, match="'detector_options'.*a dict"):
        GenerateConfig.from_toml(_toml(), ["detector_options=0.6"])


def _toml() -> str:
    from pathlib import Path

    return str(Path(__file__).parents[2] / "configs" / "mhp_scenes_heldout.toml")


def test_generate_builds_its_detector_with_the_options(tmp_path):
    synth_ready("anny", "moderngl")
    cfg = GenerateConfig.from_dict(
        {"poses": "random", "num_meshes": 1, "views": 2, "shard_size": 1, "batch_size": 1,
         "camera_preset": "h36m", "image_size": [200, 200], "seed": 3,
         "detector": _SPEC, "detector_options": {"score": 0.75}}
    )  # fmt: skip
    generate(cfg, tmp_path, progress=False)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["config"]["detector_options"] == {"score": 0.75}
    with np.load(list_shards(tmp_path)[0]) as z:
        scores = z["scores"]
    assert scores.shape == (1, 2, 17) and np.allclose(scores, 0.75)
