"""One camera with a lifter that reads the floor: the cues ``rmpl run`` then uses, the
floor reaching the network, and what the log says (issue 16)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
import torch

import rmpl
from rmpl.cli import main
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.io.poses import load_poses
from rmpl.model.lifter import RMPL, RMPLConfig
from rmpl.pipeline.monocular import FLOOR_MODEL_LIFTER_SD, MonocularConfig
from rmpl.training.loop import save_checkpoint

WALK = Path(rmpl.__file__).parent / "examples" / "walk" / "ground_truth.npz"


@pytest.fixture(scope="module")
def floor_model(tmp_path_factory) -> Path:
    model = RMPL(RMPLConfig(dim=32, depth_view=1, depth_pose=1, heads=2, floor=True))
    g = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for p in model.parameters():
            p.copy_(torch.randn(p.shape, generator=g) * 0.05)
    path = tmp_path_factory.mktemp("floor_model")
    save_checkpoint(model, path, {"model": model.config.to_dict()})
    return path


def test_cues_for_a_model_that_reads_the_floor(floor_model):
    cfg = MonocularConfig.for_model(str(floor_model))
    assert cfg.cues == ("time",) and cfg.lifter_sd == FLOOR_MODEL_LIFTER_SD
    no_floor = MonocularConfig.for_model(str(floor_model), floor_known=False)
    assert no_floor.cues == ("size", "time") and no_floor.lifter_sd == MonocularConfig().lifter_sd
    assert MonocularConfig.for_model("default") == MonocularConfig()
    assert MonocularConfig.from_cues("none").cues == ()
    with pytest.raises(InputError, match="none"):
        MonocularConfig.from_cues("floor+depth")


def _io(tmp_path: Path) -> list[str]:
    X = np.load(WALK)["points"][:, 0].astype(float)
    K = np.array([[1000.0, 0, 640], [0, 1000, 360], [0, 0, 1]])
    C = np.array([5.0, 0.5, 2.5])
    R, _ = look_at(C, np.array([0.0, 0, 1]))
    rig = Rig((Camera(K, R, -R @ C, size=(1280, 720), name="cam"),))
    kp = rig.project(X)
    doc = Keypoints2D(kp[:, :, None], np.full(kp[:, :, None].shape[:-1], 0.9), "coco17", rig.names,
                      np.arange(len(X)), 30.0)  # fmt: skip
    save_rig(rig, tmp_path / "calib.toml")
    save_keypoints(doc, tmp_path / "kp.json")
    return ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]


def test_one_camera_run_gives_the_floor_to_the_model(tmp_path, floor_model, caplog):
    io = _io(tmp_path)
    outs = {}
    for floor in ("z=0", "z=0.2", "none"):
        out = tmp_path / f"{floor}.npz"
        with caplog.at_level(logging.INFO):
            args = ["lift", *io, "--model", str(floor_model), "--floor", floor, "--out", str(out)]
            assert main(args) == 0
        outs[floor] = load_poses(out)
    assert "learnt from the floor" in caplog.text
    assert "expect a coarse depth" in caplog.text  # said for --floor none
    for poses in outs.values():
        assert np.isfinite(poses.points).all() and np.isfinite(poses.uncertainty).all()
    assert not np.allclose(outs["z=0"].points, outs["z=0.2"].points)
    assert not np.allclose(outs["z=0"].points, outs["none"].points)


def test_one_camera_report_says_where_depth_came_from(tmp_path, floor_model):
    import json

    io = _io(tmp_path)
    out = tmp_path / "run"
    assert main(["run", *io, "--model", str(floor_model), "--floor", "z=0", "--out", str(out)]) == 0
    md = (out / "report.md").read_text()
    assert "## One camera: depth from priors" in md
    assert "nothing triangulates the depth" in md
    block = json.loads((out / "report.json").read_text())["one_camera"]
    assert block["uncertainty_50_mm_median"] > 0
    assert block["uncertainty_50_mm_p90"] >= block["uncertainty_50_mm_median"]


def test_one_camera_without_a_floor_and_without_model_lifts_with_the_no_floor_model(
    tmp_path, caplog
):
    """The floor model was chosen with the floor given: with none known, rmpl lift's own
    choice is the previous one-camera path (and says so); --model keeps the user's."""
    from rmpl.models import ONE_CAMERA, ONE_CAMERA_NO_FLOOR

    assert ONE_CAMERA != ONE_CAMERA_NO_FLOOR
    io = _io(tmp_path)
    auto, given = tmp_path / "auto.npz", tmp_path / "given.npz"
    with caplog.at_level(logging.INFO):
        assert main(["lift", *io, "--floor", "none", "--out", str(auto)]) == 0
    assert f"no floor: lifting with --model {ONE_CAMERA_NO_FLOOR}" in caplog.text
    args = ["lift", *io, "--floor", "none", "--model", ONE_CAMERA_NO_FLOOR, "--out", str(given)]
    assert main(args) == 0
    assert np.array_equal(load_poses(auto).points, load_poses(given).points)


def test_evaluate_method_names_a_model_with_or_without_cues(floor_model):
    from rmpl.evaluate.methods import MonocularMethod, parse_methods

    methods = parse_methods(f"rmpl+floor@{floor_model},rmpl+floor:none@{floor_model}")
    a, b = methods.values()
    assert isinstance(a, MonocularMethod) and isinstance(b, MonocularMethod)
    assert a.config_for(floor_known=False).cues == ("size", "time")  # the run's, no floor
    assert a.config.cues == ("time",) and b.config.cues == ()
    with pytest.raises(InputError):
        parse_methods("rmpl+flor@floor26")


def test_one_video_or_view_of_a_larger_calibration_uses_that_camera(tmp_path, floor_model):
    """2D for one camera of a 2-camera calibration, named like it: that camera is used
    (as with a one-camera calibration); a name no camera has is refused."""
    from rmpl.io.calibration import load_rig

    io = _io(tmp_path)
    one = load_rig(tmp_path / "calib.toml")
    cam = one.cameras[0]
    other = Camera(cam.K, cam.R, cam.t + np.array([0.5, 0, 0]), size=cam.size, name="other")
    save_rig(Rig((other, cam)), tmp_path / "two.toml")
    outs = {}
    for calib in ("calib.toml", "two.toml"):
        out = tmp_path / f"{calib}.npz"
        args = ["lift", "--calib", str(tmp_path / calib), *io[2:], "--model", str(floor_model),
                "--floor", "z=0", "--out", str(out)]  # fmt: skip
        assert main(args) == 0
        outs[calib] = load_poses(out).points
    assert np.array_equal(outs["calib.toml"], outs["two.toml"])
    save_rig(Rig((other, Camera(cam.K, cam.R, cam.t, size=cam.size, name="third"))),
             tmp_path / "none.toml")  # fmt: skip
    args = [
        "lift",
        "--calib",
        str(tmp_path / "none.toml"),
        *io[2:],
        "--out",
        str(tmp_path / "x.npz"),
    ]
    assert main(args) == 2


def test_a_convention_floor_widens_the_radius_and_says_so(tmp_path, floor_model, caplog):
    """The same plane, once given (--floor z=0) and once taken from the calibration's
    convention: the same poses, a wider uncertainty and a warning for the guess."""
    io = _io(tmp_path)
    given, guessed = tmp_path / "given.npz", tmp_path / "guessed.npz"
    base = ["lift", *io, "--model", str(floor_model)]
    assert main([*base, "--floor", "z=0", "--out", str(given)]) == 0
    with caplog.at_level(logging.WARNING):
        assert main([*base, "--out", str(guessed)]) == 0
    assert "calibration's convention" in caplog.text and "not measured" in caplog.text
    a, b = load_poses(given), load_poses(guessed)
    assert np.allclose(a.points, b.points)
    assert (b.uncertainty > 1.1 * a.uncertainty).all()  # 0.05 m / 2.5 m beside 0.033
