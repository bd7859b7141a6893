"""The command line's bad-input corpus (issue 13): 2D keypoint files, view/camera names,
option values and outputs. Every case exits non-zero with one line naming what is wrong,
and leaves no output file."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest

from rmpl.cli import main
from tests.reliability._scene import io_args, make_scene


def refused(capsys, argv, *words, code=2) -> str:
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == code
    err = capsys.readouterr().err
    for w in words:
        assert w in err, err
    return err


def fails(capsys, argv, *words) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


# --------------------------------------------------------------------------- options (item 10)

OPTIONS = [
    ("triangulate", ["--min-score", "1.5"], "--min-score"),
    ("triangulate", ["--min-score", "-0.2"], "--min-score"),
    ("triangulate", ["--max-error", "-1"], "--max-error"),
    ("triangulate", ["--max-error", "0"], "--max-error"),
    ("triangulate", ["--fps", "0"], "--fps"),
    ("triangulate", ["--fps", "nan"], "--fps"),
    ("run", ["--cutoff", "0"], "--cutoff"),
    ("run", ["--cutoff", "-6"], "--cutoff"),
    ("run", ["--max-gap", "-1"], "--max-gap"),
    ("run", ["--min-track", "0"], "--min-track"),
    ("run", ["--fps", "-30"], "--fps"),
    ("run", ["--fps", "abc"], "--fps"),
]


@pytest.mark.parametrize("command, option, name", OPTIONS)
def test_impossible_option_values_are_refused_at_parse_time(tmp_path, capsys, command, option,
                                                            name):  # fmt: skip
    # Parse time: nothing is read, so the files need not even exist.
    argv = io_args(tmp_path, command, "out.json" if command == "triangulate" else "res")
    refused(capsys, argv + option, name, "expected")
    assert not (tmp_path / "out.json").exists() and not (tmp_path / "res").exists()


@pytest.mark.parametrize("cutoff", ["15", "40"])
def test_cutoff_at_or_above_nyquist_is_refused(tmp_path, capsys, cutoff):
    make_scene(tmp_path)  # 30 frames/s: Nyquist is 15 Hz
    argv = io_args(tmp_path, "run", "res") + ["--method", "triangulate", "--cutoff", cutoff]
    fails(capsys, argv, "--cutoff", "Nyquist", "15 Hz")
    assert not (tmp_path / "res" / "poses.json").exists()


def test_one_camera_rig_cannot_be_triangulated(tmp_path, capsys):
    make_scene(tmp_path, views=1)
    fails(capsys, io_args(tmp_path), "calib.toml", "at least 2 cameras")
    assert not (tmp_path / "out.json").exists()


@pytest.mark.parametrize("command", ["triangulate", "run"])
def test_views_that_never_share_a_frame_are_an_error(tmp_path, capsys, command):
    make_scene(tmp_path, frames=6)
    doc = json.loads((tmp_path / "kp.json").read_text())
    for t, frame in enumerate(doc["keypoints"]):  # frame t seen by view t % 3 only
        for v in range(3):
            if v != t % 3:
                frame[v] = [[[None, None]] * 17]
                doc["scores"][t][v] = [[0.0] * 17]
    (tmp_path / "kp.json").write_text(json.dumps(doc))
    argv = io_args(tmp_path, command, "out.json" if command == "triangulate" else "res")
    argv += ["--method", "triangulate"] if command == "run" else []
    fails(capsys, argv, "nothing estimated", "two views")
    assert not (tmp_path / "out.json").exists() and not (tmp_path / "res" / "poses.npz").exists()


# --------------------------------------------------------------------------- views (item 9)


def test_partial_view_name_match_is_refused(tmp_path, capsys):
    make_scene(tmp_path, names=["cam0", "cam1", "side"])
    err = fails(capsys, io_args(tmp_path), "views ['side'] have no camera", "cameras ['cam2']")
    assert "by order" in err
    assert not (tmp_path / "out.json").exists()


def test_no_name_match_pairs_by_order_with_a_warning(tmp_path, caplog):
    make_scene(tmp_path, names=["a", "b", "c"])
    with caplog.at_level(logging.WARNING):
        assert main(io_args(tmp_path)) == 0
    assert any(r.levelno == logging.WARNING and "by order" in r.getMessage()
               for r in caplog.records)  # fmt: skip


def test_views_named_in_another_order_are_matched_by_name(tmp_path, caplog):
    rig, X, kp, sc = make_scene(tmp_path)
    from rmpl.io.keypoints import Keypoints2D, save_keypoints
    from rmpl.io.poses import load_poses

    order = [2, 0, 1]
    shuffled = Keypoints2D(kp[:, order, None], sc[:, order, None], "coco17",
                           [rig.names[i] for i in order], None, 30.0)  # fmt: skip
    save_keypoints(shuffled, tmp_path / "kp.json")
    with caplog.at_level(logging.WARNING):
        assert main(io_args(tmp_path)) == 0
    assert "by order" not in caplog.text
    np.testing.assert_allclose(load_poses(tmp_path / "out.json").points[:, 0], X, atol=1e-6)


# --------------------------------------------------------------------------- pixels (item 11)


def test_absurd_pixels_are_missing_and_reported(tmp_path, caplog):
    from rmpl.io.poses import load_poses

    rig, X, kp, sc = make_scene(tmp_path)
    doc = json.loads((tmp_path / "kp.json").read_text())
    doc["keypoints"][2][1][0][0] = [1e12, 5e14]  # 1e12 px in a 960 x 720 image
    doc["keypoints"][3][0][0][5] = [-2000.0, 100.0]  # more than one width left of the image
    (tmp_path / "kp.json").write_text(json.dumps(doc))
    with caplog.at_level(logging.WARNING):
        assert main(io_args(tmp_path)) == 0
    assert "2 of 408 keypoints" in caplog.text
    poses = load_poses(tmp_path / "out.json")
    assert poses.num_views[2, 0, 0] == 2 and poses.num_views[3, 0, 5] == 2
    assert np.nanmax(np.linalg.norm(poses.points[:, 0] - X, axis=-1)) < 1e-3


def test_points_just_outside_the_image_are_kept(tmp_path, caplog):
    make_scene(tmp_path)
    doc = json.loads((tmp_path / "kp.json").read_text())
    doc["keypoints"][2][1][0][0] = [1500.0, -300.0]  # outside, but within one image size
    (tmp_path / "kp.json").write_text(json.dumps(doc))
    with caplog.at_level(logging.WARNING):
        assert main(io_args(tmp_path)) == 0
    assert "beyond their image" not in caplog.text


# --------------------------------------------------------------------------- 2D files


def _rmpl_json(tmp_path, **change):
    make_scene(tmp_path)
    doc = json.loads((tmp_path / "kp.json").read_text())
    doc.update(change)
    (tmp_path / "kp.json").write_text(json.dumps(doc))


KEYPOINT_FILES = {
    "empty file": (lambda p: (p / "kp.json").write_text(""), "empty file"),
    "truncated JSON": (lambda p: (p / "kp.json").write_text('{"format": "rmpl.key'), "valid JSON"),
    "binary file": (lambda p: (p / "kp.json").write_bytes(b"\xff\xfe\x00" * 50), "UTF-8"),
    "missing views": (lambda p: _rmpl_json(p, views=None), "views"),
    "wrong skeleton": (lambda p: _rmpl_json(p, skeleton="body99"), "skeleton"),
    "negative people": (lambda p: _rmpl_json(p, num_people=-1), "num_people"),
    "mismatched lengths": (lambda p: _rmpl_json(p, frames=[0, 1, 2]), "keypoints"),
    "text keypoints": (lambda p: _rmpl_json(p, keypoints="none"), "keypoints"),
}


@pytest.mark.parametrize("case", sorted(KEYPOINT_FILES))
def test_broken_keypoint_files(tmp_path, capsys, case):
    make_scene(tmp_path)
    damage, word = KEYPOINT_FILES[case]
    damage(tmp_path)
    fails(capsys, io_args(tmp_path), "kp.json", word)
    assert not (tmp_path / "out.json").exists()


def test_empty_openpose_folder(tmp_path, capsys):
    make_scene(tmp_path)
    (tmp_path / "pose" / "cam0_json").mkdir(parents=True)
    argv = io_args(tmp_path)
    argv[argv.index("--keypoints") + 1] = str(tmp_path / "pose")
    fails(capsys, argv, "pose", "no JSON file")


def test_openpose_frame_with_nobody_everywhere_is_an_error(tmp_path, capsys):
    make_scene(tmp_path)
    for v in range(3):
        d = tmp_path / "pose" / f"cam{v}_json"
        d.mkdir(parents=True)
        for t in range(3):
            (d / f"cam{v}_{t:06d}_keypoints.json").write_text('{"people": []}')
    argv = io_args(tmp_path)
    argv[argv.index("--keypoints") + 1] = str(tmp_path / "pose")
    fails(capsys, argv, "confidence > 0")


# --------------------------------------------------------------------------- outputs


@pytest.mark.parametrize("name", ["out.txt", "out", "out.json.bak"])
def test_output_of_an_unknown_kind(tmp_path, capsys, name):
    make_scene(tmp_path)
    fails(capsys, io_args(tmp_path, out=name), name, "expected an output file")


def test_unknown_run_format(tmp_path, capsys):
    make_scene(tmp_path)
    argv = io_args(tmp_path, "run", "res") + ["--formats", "npz,fbx"]
    fails(capsys, argv, "--formats", "fbx")


def test_c3d_of_many_people_through_run(tmp_path):
    """The 16+ people C3D crash (item 2) through the command: 20 people, spread apart."""
    from rmpl.geometry.camera import Camera, Rig, look_at
    from rmpl.io.calibration import save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints
    from rmpl.io.poses import load_poses

    K = np.array([[900.0, 0, 960], [0, 900, 540], [0, 0, 1]])
    eyes = [[12, 0, 8], [0, 12, 8], [-12, 0, 8], [0, -12, 8]]
    rig = Rig(tuple(Camera(K, *look_at(np.array(e, float), np.zeros(3)), size=(1920, 1080),
                           name=f"c{i}") for i, e in enumerate(eyes)))  # fmt: skip
    rng = np.random.default_rng(1)
    P, T = 20, 4
    centres = np.stack(np.meshgrid(np.arange(5) * 1.5 - 3, np.arange(4) * 1.5 - 2), -1)
    X = rng.uniform(-0.2, 0.2, (T, P, 17, 3)) + np.c_[centres.reshape(-1, 2), np.ones(P)][:, None]
    kp = rig.project(X.reshape(T, P * 17, 3)).reshape(T, 4, P, 17, 2)
    save_rig(rig, tmp_path / "calib.toml")
    save_keypoints(Keypoints2D(kp, np.full(kp.shape[:-1], 0.9), fps=30.0), tmp_path / "kp.json")
    argv = io_args(tmp_path, "run", "res") + ["--method", "triangulate", "--no-pictures",
                                              "--min-track", "1"]  # fmt: skip
    assert main(argv) == 0
    assert load_poses(tmp_path / "res" / "poses.npz").num_people == P
    assert (tmp_path / "res" / "poses.c3d").stat().st_size > 0


@pytest.mark.parametrize("which", ["kp.json", "calib.toml"])
def test_unreadable_input(tmp_path, capsys, monkeypatch, which):
    # The tests may run as root, who reads anything: the file refuses reads instead.
    from pathlib import Path

    make_scene(tmp_path)
    real_read, real_open = Path.read_text, Path.open

    def locked(self, *args, **kwargs):
        if self.name == which:
            raise PermissionError(13, "Permission denied", str(self))
        return real_read(self, *args, **kwargs)

    def locked_open(self, *args, **kwargs):
        if self.name == which:
            raise PermissionError(13, "Permission denied", str(self))
        return real_open(self, *args, **kwargs)

    monkeypatch.setattr(Path, "read_text", locked)
    monkeypatch.setattr(Path, "open", locked_open)
    fails(capsys, io_args(tmp_path), which, "Permission denied")
    assert not (tmp_path / "out.json").exists()
