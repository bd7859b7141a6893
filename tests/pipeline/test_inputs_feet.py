"""The run's inputs keep the feet, neck, head top and mid-hip of real 2D: Inputs.skeleton."""

import numpy as np
import pytest

from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.pipeline.inputs import InputSpec, load_inputs
from rmpl.skeleton import HALPE26
from tests.pipeline.test_consistency import make_rig

DEMO = "pose2sim_demo/Pose2Sim/S01_Demo_SingleTrial"


def _seen(scores, names):
    return {n: bool((scores[..., HALPE26.index(n)] > 0).any()) for n in names}


@pytest.mark.shared
def test_pose2sim_demo_inputs_are_halpe26(shared_data):
    root = shared_data / DEMO
    spec = InputSpec(
        calib=str(root / "calibration" / "Calib.qca.txt"), keypoints=[str(root / "pose")]
    )
    inputs = load_inputs(spec)
    assert inputs.skeleton == "halpe26" and inputs.keypoints.shape[-2] == 26
    seen = _seen(inputs.scores, HALPE26.joints[17:])
    # BODY_25B: no mid-hip, and its upper neck is not HALPE-26's neck
    assert seen == {**dict.fromkeys(HALPE26.joints[17:], True), "mid_hip": False, "neck": False}


@pytest.mark.shared
def test_shelf_candidates_grouped_into_halpe26(shared_data):
    from rmpl.data.shelf import load_shelf
    from rmpl.pipeline.association import group_people
    from rmpl.pipeline.inputs import _shelf4d_keypoints

    root = shared_data / "shelf_dev"
    kp = _shelf4d_keypoints(root)
    assert kp.skeleton == "halpe26"
    seen = _seen(kp.scores, HALPE26.joints[17:])
    assert seen == {**dict.fromkeys(HALPE26.joints[17:], True), "head_top": False}  # BODY_25
    # the COCO-17 part is what COCO-17 grouping gives (frame 0)
    data = load_shelf(root)
    for v, cands in enumerate(data.detections[0]):
        coco, coco_sc = group_people(cands, output="coco17")
        np.testing.assert_array_equal(kp.keypoints[0, v, : len(coco), :17], coco)
        np.testing.assert_array_equal(kp.scores[0, v, : len(coco), :17], coco_sc)


def test_coco17_file_inputs_stay_coco17(tmp_path):
    rig = make_rig(2)
    save_rig(rig, tmp_path / "calib.toml")
    rng = np.random.default_rng(0)
    kp = Keypoints2D(
        rng.uniform(0, 900, (3, 2, 1, 17, 2)), np.full((3, 2, 1, 17), 0.9), "coco17", rig.names
    )
    save_keypoints(kp, tmp_path / "kp.npz")
    inputs = load_inputs(
        InputSpec(calib=str(tmp_path / "calib.toml"), keypoints=[str(tmp_path / "kp.npz")])
    )
    assert inputs.skeleton == "coco17"
    np.testing.assert_array_equal(inputs.keypoints, kp.keypoints)
