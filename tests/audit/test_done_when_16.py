"""Audit of issue 16's "Done when" tests: what the existing floor tests left out.

- floor absent by default: a calibration with no convention and no --floor warns and lifts
  exactly as ``--floor none`` does (the existing tests give ``none`` explicitly);
- floor estimated from a multi-view poses file: used, and it fixes the depth as well as the
  right plane given by hand (the existing test reads only the log line);
- bad input: an estimated floor that lies above the camera names the poses file.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

import rmpl
from rmpl.cli import main
from rmpl.geometry.camera import Camera, Rig, look_at, rodrigues
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.io.poses import Poses3D, load_poses, save_poses

WALK = Path(rmpl.__file__).parent / "examples" / "walk" / "ground_truth.npz"
HIPS = [11, 12]  # COCO-17 (and HALPE-26) left and right hip


def _walk() -> np.ndarray:
    """The shipped walk, (60, 17, 3) metres, z up, ankles resting ~0.1 m above z = 0."""
    return np.load(WALK)["points"][:, 0].astype(float)


def _one_camera(tmp_path: Path, roll_deg: float = 0.0) -> tuple[np.ndarray, list[str]]:
    """The walk seen by one camera 2.5 m up, rolled ``roll_deg`` about its optical axis;
    writes calib.toml and kp.json (COCO-17, 30 frames/s). Returns the truth and the I/O args."""
    X = _walk()
    K = np.array([[1000.0, 0, 640], [0, 1000, 360], [0, 0, 1]])
    R, _ = look_at(np.array([5.0, 0.5, 2.5]), np.array([0.0, 0, 1]))
    R = rodrigues(np.array([0, 0, np.radians(roll_deg)])) @ R
    C = np.array([5.0, 0.5, 2.5])
    rig = Rig((Camera(K, R, -R @ C, size=(1280, 720), name="cam"),))
    kp = rig.project(X)  # (60, 1, 17, 2)
    sc = np.full(kp.shape[:-1], 0.9)
    save_rig(rig, tmp_path / "calib.toml")
    doc = Keypoints2D(kp[:, :, None], sc[:, :, None], "coco17", rig.names, np.arange(60), 30.0)
    save_keypoints(doc, tmp_path / "kp.json")
    return X, ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]


def _root_error(path: Path, X: np.ndarray) -> float:
    p = load_poses(path).points[:, 0]
    return float(np.linalg.norm(p[:, HIPS].mean(1) - X[:, HIPS].mean(1), axis=-1).mean())


def test_no_floor_known_warns_and_lifts_as_floor_none(tmp_path, caplog):
    """A camera rolled 40 degrees: the calibration states no convention, no --floor given.
    The lift warns that depth comes from body size and time only, and equals --floor none
    (no floor is made up)."""
    X, io = _one_camera(tmp_path, roll_deg=40)
    default, none = tmp_path / "default.npz", tmp_path / "none.npz"
    with caplog.at_level(logging.WARNING):
        assert main(["lift", *io, "--out", str(default)]) == 0
    assert "no floor known" in caplog.text and "--floor" in caplog.text
    assert main(["lift", *io, "--out", str(none), "--floor", "none"]) == 0
    a, b = load_poses(default).points, load_poses(none).points
    assert np.isfinite(a).all() and np.array_equal(a, b)


def test_a_floor_estimated_from_a_multi_view_run_fixes_the_depth(tmp_path, caplog):
    """The floor estimated from a multi-view run's poses of the same room (ankles at the
    walk's heights) is the floor the walk stands on: the root lands as close as with that
    plane given by hand, and much closer than with no floor."""
    X, io = _one_camera(tmp_path)
    wide = np.concatenate([X + [dx, dy, 0.0] for dx in (-1.5, 1.5) for dy in (-1.5, 1.5)])
    save_poses(Poses3D(wide[:, None], skeleton="coco17"), tmp_path / "multi.npz")
    runs = {"estimated": str(tmp_path / "multi.npz"), "given": "z=0.03", "none": "none"}
    err = {}
    for name, floor in runs.items():
        out = tmp_path / f"{name}.npz"
        with caplog.at_level(logging.INFO):
            assert main(["lift", *io, "--out", str(out), "--floor", floor]) == 0
        err[name] = _root_error(out, X)
    assert "estimated from 240 ankle positions" in caplog.text
    assert err["estimated"] < 0.2 and err["estimated"] < 0.5 * err["none"], err
    assert err["estimated"] == pytest.approx(err["given"], abs=0.03), err


def test_an_estimated_floor_above_the_camera_names_the_poses_file(tmp_path, capsys):
    """Poses of another room (ankles 4 m up, the camera is 2.5 m up): one line, exit 2,
    naming the file and the expectation; nothing written."""
    X, io = _one_camera(tmp_path)
    wide = np.concatenate([X + [dx, dy, 4.0] for dx in (-1.5, 1.5) for dy in (-1.5, 1.5)])
    save_poses(Poses3D(wide[:, None], skeleton="coco17"), tmp_path / "attic.npz")
    out = tmp_path / "o.npz"
    assert main(["lift", *io, "--out", str(out), "--floor", str(tmp_path / "attic.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "attic.npz" in err and "below the cameras" in err, err
    assert not out.exists()
