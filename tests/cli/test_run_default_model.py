"""rmpl run's model when --model is not given: the temporal model with two or more cameras
and a frame rate, else the per-frame model, said in the log."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from rmpl.cli import main
from rmpl.io.poses import load_poses
from rmpl.models import ONE_CAMERA, PER_FRAME, TEMPORAL, choose_model

EXAMPLE = Path(__file__).resolve().parents[2] / "src/rmpl/examples/walk"


def test_default_model_rule(caplog):
    from rmpl.inference import PRETRAINED
    from rmpl.inference_temporal import PRETRAINED_TEMPORAL

    assert PER_FRAME in PRETRAINED and ONE_CAMERA in PRETRAINED
    assert TEMPORAL in PRETRAINED_TEMPORAL
    assert choose_model(4, 30.0, "rmpl") == TEMPORAL
    assert choose_model(1, 30.0, "rmpl") == ONE_CAMERA  # one camera: the floor path
    assert choose_model(4, 30.0, "triangulate") == PER_FRAME
    with caplog.at_level(logging.WARNING):
        assert choose_model(4, None, "rmpl") == PER_FRAME
    assert any("no frame rate" in r.getMessage() for r in caplog.records)


def test_rmpl_run_lifts_whole_tracks_by_default_and_per_frame_on_request(tmp_path):
    """The embedded walk (4 cameras, a frame rate): the default run carries the temporal
    model's error radii; --model default does not, and its answers differ."""
    base = ["run", "--calib", str(EXAMPLE / "calibration.toml"), "--keypoints",
            str(EXAMPLE / "keypoints.json"), "--no-pictures", "--pose2sim", "off"]  # fmt: skip
    assert main([*base, "--out", str(tmp_path / "t")]) == 0
    assert main([*base, "--model", "default", "--out", str(tmp_path / "f")]) == 0
    temporal, frame = (load_poses(tmp_path / x / "poses.npz") for x in ("t", "f"))
    assert temporal.uncertainty is not None and np.isfinite(temporal.uncertainty).any()
    assert frame.uncertainty is None
    truth = np.load(EXAMPLE / "ground_truth.npz")["points"][:, 0]
    for poses in (temporal, frame):
        err = np.linalg.norm(poses.points[:, 0, :17] - truth, axis=-1)  # COCO-17 joints
        assert np.nanmean(err) < 0.06  # both lift the walk (about 3-4 cm)
    assert not np.allclose(temporal.points[..., :17, :], frame.points, equal_nan=True)
