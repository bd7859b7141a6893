"""2D readers keep the feet, neck, head top and mid-hip of the files (HALPE-26 results)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rmpl.io.keypoints import load_keypoints, richest, save_keypoints
from rmpl.skeleton import BLAZEPOSE33, BODY25, BODY25B, COCO17, HALPE26

# Written out here independently of the reader: AlphaPose's Halpe-26 order and the first 23
# points of COCO-WholeBody (the COCO-17 body, then the feet).
HALPE_ORDER = COCO17.joints + (
    "head_top",
    "neck",
    "mid_hip",
    "left_big_toe",
    "right_big_toe",
    "left_small_toe",
    "right_small_toe",
    "left_heel",
    "right_heel",
)
WHOLEBODY_FIRST23 = COCO17.joints + (
    "left_big_toe",
    "left_small_toe",
    "left_heel",
    "right_big_toe",
    "right_small_toe",
    "right_heel",
)
FEET = ("left_big_toe", "right_big_toe", "left_small_toe", "right_small_toe")
HEELS = ("left_heel", "right_heel")
DEMO = Path("pose2sim_demo/Pose2Sim/S01_Demo_SingleTrial")


def _person(num_joints: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(10.0, 900.0, size=(num_joints, 2))
    return np.concatenate([xy, rng.uniform(0.1, 1.0, size=(num_joints, 1))], axis=1)


def _write_openpose(d: Path, frame: int, people: list[np.ndarray]) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    doc = {"people": [{"pose_keypoints_2d": p.reshape(-1).tolist()} for p in people]}
    path = d / f"{d.name}.{frame:04d}.json"
    path.write_text(json.dumps(doc))
    return path


def _check_by_name(kp, p: np.ndarray, names: tuple[str, ...], frame=0, view=0, person=0):
    """Each HALPE-26 joint holds the file's point of the same name; the others are missing."""
    got, score = kp.keypoints[frame, view, person], kp.scores[frame, view, person]
    for j, name in enumerate(HALPE26.joints):
        if name in names:
            np.testing.assert_array_equal(got[j], p[names.index(name), :2])
            assert score[j] == p[names.index(name), 2]
        else:
            assert np.isnan(got[j]).all() and score[j] == 0, name


@pytest.mark.parametrize("ext", [".npz", ".json"])
def test_body25_keeps_feet_neck_mid_hip_through_a_round_trip(tmp_path, ext):
    p = _person(25, 1)
    _write_openpose(tmp_path / "cam0", 0, [p])
    kp = load_keypoints(tmp_path / "cam0")
    assert kp.skeleton == "halpe26" and kp.num_joints == 26
    _check_by_name(kp, p, BODY25.joints)  # no head top in BODY_25
    assert np.isnan(kp.keypoints[0, 0, 0, HALPE26.index("head_top")]).all()

    back = load_keypoints(save_keypoints(kp, tmp_path / f"kp{ext}"))
    assert back.skeleton == "halpe26"
    np.testing.assert_array_equal(back.keypoints, kp.keypoints)
    np.testing.assert_array_equal(back.scores, kp.scores)
    coco = load_keypoints(tmp_path / f"kp{ext}", to="coco17")
    np.testing.assert_array_equal(coco.keypoints, kp.keypoints[..., :17, :])


def test_body25b_gives_head_top_but_not_its_upper_neck(tmp_path):
    p = _person(25, 2)
    _write_openpose(tmp_path / "cam0", 0, [p])
    kp = load_keypoints(tmp_path / "cam0", skeleton="body25b")
    assert kp.skeleton == "halpe26"
    _check_by_name(kp, p, BODY25B.joints)  # everything but the mid-hip and the neck
    assert np.isnan(kp.keypoints[0, 0, 0, HALPE26.index("neck")]).all()


def test_pose2sim_config_names_the_model(tmp_path):
    """Pose2Sim's RTMPose presets: 'Body_with_feet' is HALPE-26 in OpenPose JSON."""
    p = _person(26, 3)
    _write_openpose(tmp_path / "pose" / "cam0_json", 0, [p])
    (tmp_path / "Config.toml").write_text("[pose]\npose_model = 'Body_with_feet'\n")
    kp = load_keypoints(tmp_path / "pose")
    assert kp.skeleton == "halpe26" and kp.views == ["cam0"]
    _check_by_name(kp, p, HALPE_ORDER)


@pytest.mark.parametrize("to", ["auto", None])
def test_halpe26_openpose_json_is_read_as_it_is(tmp_path, to):
    people = [_person(26, 4), _person(26, 5)]
    _write_openpose(tmp_path / "cam0", 7, people)
    kp = load_keypoints(tmp_path / "cam0", to=to)
    assert kp.skeleton == "halpe26" and kp.frames.tolist() == [7]
    for i, p in enumerate(people):
        _check_by_name(kp, p, HALPE_ORDER, person=i)


def test_wholebody133_feet_reordered(tmp_path):
    p = _person(133, 6)
    _write_openpose(tmp_path / "cam0", 0, [p])
    kp = load_keypoints(tmp_path / "cam0")
    assert kp.skeleton == "halpe26"
    _check_by_name(kp, p, WHOLEBODY_FIRST23)  # no head top, neck, mid-hip: NaN


def test_wholebody133_coco_instances_keep_feet(tmp_path):
    p = _person(133, 7)
    doc = [{"keypoints": p[:, :2].tolist(), "keypoint_scores": p[:, 2].tolist()}]
    (tmp_path / "img_00003.json").write_text(json.dumps(doc))
    kp = load_keypoints(tmp_path / "img_00003.json")
    assert kp.skeleton == "halpe26" and kp.frames.tolist() == [3]
    _check_by_name(kp, p, WHOLEBODY_FIRST23)


def test_coco18_gives_the_neck(tmp_path):
    names = (
        "nose",
        "neck",
        "right_shoulder",
        "right_elbow",
        "right_wrist",
        "left_shoulder",
        "left_elbow",
        "left_wrist",
        "right_hip",
        "right_knee",
        "right_ankle",
        "left_hip",
        "left_knee",
        "left_ankle",
        "right_eye",
        "left_eye",
        "right_ear",
        "left_ear",
    )
    p = _person(18, 8)
    _write_openpose(tmp_path / "cam0", 0, [p])
    kp = load_keypoints(tmp_path / "cam0")
    assert kp.skeleton == "halpe26"
    _check_by_name(kp, p, names)


def test_blazepose_heels_and_foot_index_in_the_big_toe_slot(tmp_path):
    p = _person(33, 9)
    _write_openpose(tmp_path / "cam0", 0, [p])
    kp = load_keypoints(tmp_path / "cam0")
    assert kp.skeleton == "halpe26"
    got = kp.keypoints[0, 0, 0]
    for name in HEELS + COCO17.joints:
        np.testing.assert_array_equal(got[HALPE26.index(name)], p[BLAZEPOSE33.index(name), :2])
    for side in ("left", "right"):
        np.testing.assert_array_equal(
            got[HALPE26.index(f"{side}_big_toe")], p[BLAZEPOSE33.index(f"{side}_foot_index"), :2]
        )
        assert np.isnan(got[HALPE26.index(f"{side}_small_toe")]).all()
    assert np.isnan(got[HALPE26.indices(["head_top", "neck", "mid_hip"])]).all()


def test_missing_foot_stays_missing(tmp_path):
    p = _person(25, 10)
    p[BODY25.index("left_heel")] = 0.0  # OpenPose's undetected joint
    _write_openpose(tmp_path / "cam0", 0, [p])
    kp = load_keypoints(tmp_path / "cam0")
    j = HALPE26.index("left_heel")
    assert np.isnan(kp.keypoints[0, 0, 0, j]).all() and kp.scores[0, 0, 0, j] == 0


def test_coco17_input_unchanged(tmp_path):
    """A COCO-17 file reads as COCO-17, the same arrays as asking for COCO-17."""
    people = [_person(17, 11), _person(17, 12)]
    _write_openpose(tmp_path / "cam0", 0, people)
    default = load_keypoints(tmp_path / "cam0")
    asked = load_keypoints(tmp_path / "cam0", to="coco17")
    assert default.skeleton == "coco17" and default.num_joints == 17
    np.testing.assert_array_equal(default.keypoints, asked.keypoints)
    np.testing.assert_array_equal(default.scores, asked.scores)
    for i, p in enumerate(people):
        np.testing.assert_array_equal(default.keypoints[0, 0, i], p[:, :2])
    saved = save_keypoints(default, tmp_path / "kp.npz")
    assert load_keypoints(saved).skeleton == "coco17"


def test_coco17_from_a_richer_file_equals_the_first_17(tmp_path):
    p = _person(25, 13)
    _write_openpose(tmp_path / "cam0", 0, [p])
    rich = load_keypoints(tmp_path / "cam0")
    coco = load_keypoints(tmp_path / "cam0", to="coco17")
    np.testing.assert_array_equal(coco.keypoints, rich.keypoints[..., :17, :])
    np.testing.assert_array_equal(coco.scores, rich.scores[..., :17])


def test_richest_joint_set():
    assert [richest(n) for n in ("coco17", "body25", "body25b", "coco18", "blazepose33")] == [
        "coco17",
        "halpe26",
        "halpe26",
        "halpe26",
        "halpe26",
    ]
    assert richest("h36m17") == "coco17"  # no eyes or ears: not COCO-17, converted as before


@pytest.mark.shared
def test_pose2sim_demo_carries_feet(shared_data):
    """The Pose2Sim demo (OpenPose BODY_25B) gives heels, toes and head top; its upper neck
    (under the head) is not HALPE-26's neck (the base of the neck)."""
    kp = load_keypoints(shared_data / DEMO / "pose")
    assert kp.skeleton == "halpe26"
    seen = (kp.scores > 0).any(axis=(0, 1, 2))  # (J,)
    for name in HEELS + FEET + ("head_top",):
        assert seen[HALPE26.index(name)], name
    assert not seen[HALPE26.indices(["mid_hip", "neck"])].any()  # BODY_25B has neither
    # Pixels go down: heels below the knees in every view.
    y = kp.keypoints[..., 1]
    for v in range(kp.num_views):
        heels = np.nanmedian(y[:, v, :, HALPE26.indices(HEELS)])
        knees = np.nanmedian(y[:, v, :, HALPE26.indices(["left_knee", "right_knee"])])
        assert heels > knees
