"""The run report's calibration line: a camera whose held-out error (its 2D against the
people placed by the other cameras) is far above the others' may have moved."""

from __future__ import annotations

import json
from importlib.resources import files

import numpy as np

from rmpl.cli import main
from rmpl.io.calibration import load_rig, save_rig
from rmpl.pipeline.consistency import moved_cameras

EXAMPLE = files("rmpl") / "examples" / "walk"


def test_the_rule_names_only_a_camera_far_above_the_others():
    assert moved_cameras([2.0, 3.0, 40.0, 2.5]).tolist() == [False, False, True, False]
    assert not moved_cameras([2.0, 3.0, 9.0, 2.5]).any()  # under 10 px
    assert not moved_cameras([20.0, 25.0, 30.0]).any()  # not 3x the others
    assert not moved_cameras([2.0, 40.0]).any()  # two cameras cannot tell which moved
    assert not moved_cameras([2.0, np.nan, 40.0]).any()  # one camera unmeasured


def _run(tmp_path, calib, name):
    out = tmp_path / name
    argv = ["run", "--calib", str(calib), "--keypoints", str(EXAMPLE / "keypoints.json"),
            "--method", "triangulate", "--out", str(out), "--formats", "npz",
            "--no-pictures", "--pose2sim", "off"]  # fmt: skip
    assert main(argv) in (0, 3)
    report = json.loads((out / "report.json").read_text())
    return {c["camera"]: c for c in report["cameras"]}, (out / "report.md").read_text()


def test_a_turned_camera_is_named_in_the_run_report(tmp_path):
    cams, md = _run(tmp_path, EXAMPLE / "calibration.toml", "intact")
    assert not any(c["moved_since_calibration"] for c in cams.values())
    assert all(c["held_out_px_median"] is not None for c in cams.values())
    assert "no camera appears to have moved" in md
    rig = load_rig(EXAMPLE / "calibration.toml")
    a = np.radians(3.0)  # turn the third camera about its own vertical axis, in place
    turn = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    cam = rig[2]
    R = turn @ cam.R
    bumped = type(rig)(tuple(
        c if v != 2 else type(c)(c.K, R, -R @ cam.center, c.dist, c.size, c.name)
        for v, c in enumerate(rig)
    ))  # fmt: skip
    save_rig(bumped, tmp_path / "bumped.toml")
    cams, md = _run(tmp_path, tmp_path / "bumped.toml", "bumped")
    name = rig.names[2]
    assert cams[name]["moved_since_calibration"], cams
    assert [n for n, c in cams.items() if c["moved_since_calibration"]] == [name]
    assert f"{name} may have moved since calibration" in md
