"""rmpl example's comparison: the line that says which method wins where."""

from __future__ import annotations

import numpy as np

from rmpl.evaluate.example import METHODS, Score, _views, example_inputs, verdict


def test_verdict_names_the_lowest_error_of_each_setting_and_its_coverage():
    scores = {
        "4 cameras": {"rmpl": Score(37.0, 26.0, 100.0), "robust": Score(33.0, 22.0, 100.0)},
        "2 cameras": {"rmpl": Score(60.0, 50.0, 100.0), "robust": Score(50.0, 41.0, 90.0)},
    }
    line = verdict(scores)
    assert line.count(METHODS["robust"]) == 2 and METHODS["rmpl"] not in line
    assert "90% of the joints" in line and "(33.0 mm)" in line
    scores["2 cameras"]["rmpl"] = Score(45.0, 40.0, 100.0)
    assert f"with 2 cameras {METHODS['rmpl']} (45.0 mm)" in verdict(scores)


def test_a_pair_of_cameras_keeps_their_2d_and_calibration():
    inputs, gt = example_inputs()
    pair = _views(inputs, (1, 3))
    assert pair.rig.names == [inputs.rig.names[1], inputs.rig.names[3]]
    assert np.array_equal(pair.keypoints, inputs.keypoints[:, [1, 3]], equal_nan=True)
    assert gt.shape == (len(inputs.frames), 17, 3)
