"""``rmpl calibrate`` on the tiny rendered sets: cameras recovered, every format written and
read back, the report, and bad input as one line with nothing written."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.io.calibration import load_rig


def _args(spec, folder, names, out, *extra):
    return [
        "calibrate", "--board", spec, "--no-progress", "--out", str(out),
        "--intrinsics", *[str(folder / "intrinsics" / n) for n in names],
        "--extrinsics", *[str(folder / "extrinsics" / n) for n in names], *extra,
    ]  # fmt: skip


def _angle(Ra, Rb):
    return np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1, 1)))


def _similar(found, truth):
    """Umeyama: scale s, rotation, shift that best map found centres onto the true ones."""
    a, b = found.centers, truth.centers
    ma, mb = a.mean(0), b.mean(0)
    U, S, Vt = np.linalg.svd((b - mb).T @ (a - ma))
    D = np.diag([1, 1, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    s = np.trace(np.diag(S) @ D) / ((a - ma) ** 2).sum()
    return s, R, mb - s * R @ ma


@pytest.mark.parametrize("which", ["tiny_charuco", "tiny_checkerboard"])
def test_cameras_recovered(which, request, tmp_path):
    spec, scene, folder = request.getfixturevalue(which)
    truth = scene.rig
    out = tmp_path / "calib.toml"
    assert main(_args(spec, folder, truth.names, out)) == 0
    rig = load_rig(out)
    assert rig.names == truth.names
    s, R, shift = _similar(rig, truth)
    # 480x360 and two shared views a link: the full-size targets (0.3 %, 0.15 deg,
    # 10 mm, 0.5 %) scaled by five
    assert abs(s - 1) < 0.025
    for cam, true in zip(rig, truth, strict=True):
        assert abs(cam.K[0, 0] / true.K[0, 0] - 1) < 0.015
        assert np.linalg.norm(s * R @ cam.center + shift - true.center) < 0.05
        assert _angle(cam.R @ R.T, true.R) < 1.0
    if which == "tiny_charuco":  # the world is the floor board's: no alignment needed
        assert np.abs(rig.centers - truth.centers).max() < 0.06
    report = (tmp_path / "calibration.md").read_text()
    assert all(n in report for n in truth.names)
    assert (tmp_path / "calibration.json").is_file() and (tmp_path / "calibration.png").is_file()


@pytest.fixture(scope="module")
def calibrated(tiny_charuco):
    from rmpl.calibration.boards import parse_board
    from rmpl.calibration.calibrate import calibrate_boards

    spec, scene, folder = tiny_charuco
    names = scene.rig.names
    return calibrate_boards(
        parse_board(spec), [folder / "intrinsics" / n for n in names],
        [folder / "extrinsics" / n for n in names], progress=False,
    )  # fmt: skip


@pytest.mark.parametrize(
    "fmt, name", [("pose2sim", "Calib.toml"), ("anipose", "calibration.toml"),
                  ("easymocap", "easymocap"), ("rmpl-json", "calib.json"), (None, "c.toml")],
)  # fmt: skip
def test_each_format_reads_back(fmt, name, calibrated, tmp_path):
    from rmpl.calibration.output import write_calibration

    out = tmp_path / name
    written = write_calibration(calibrated, out, fmt)
    assert all(p.exists() for p in written)
    back = load_rig(out)
    assert back.names == calibrated.rig.names
    assert np.allclose(back.K, calibrated.rig.K, atol=1e-6)
    assert np.allclose(back.centers, calibrated.rig.centers, atol=1e-6)
    assert np.allclose(back.dist, calibrated.rig.dist, atol=1e-9)


def test_origin_at_a_camera(tiny_charuco, tmp_path):
    spec, scene, folder = tiny_charuco
    out = tmp_path / "c.toml"
    assert main(_args(spec, folder, scene.rig.names, out, "--origin", "camera:cam2")) == 0
    cam = load_rig(out)[1]
    assert np.allclose(cam.R, np.eye(3), atol=1e-9) and np.allclose(cam.t, 0, atol=1e-9)


def _fails(capsys, argv, *words):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


def test_a_camera_sharing_no_view(tiny_charuco, tmp_path, capsys):
    spec, scene, folder = tiny_charuco
    import cv2

    ext = tmp_path / "ext"
    blank = np.full((360, 480), 110, np.uint8)
    for n in scene.rig.names:  # cam1, cam2 see the board at instants 0-3, cam3 at 4-7 only
        (ext / n).mkdir(parents=True)
        for i in range(8):
            src = folder / "extrinsics" / n / f"{i % 4:03d}.png"
            shows = (i < 4) != (n == "cam3")
            image = cv2.imread(str(src), cv2.IMREAD_GRAYSCALE) if shows else blank
            cv2.imwrite(str(ext / n / f"{i:03d}.png"), image)
    out = tmp_path / "never" / "calib.toml"
    argv = _args(spec, folder, scene.rig.names, out)
    argv[argv.index("--extrinsics") + 1 :] = [str(ext / n) for n in scene.rig.names]
    _fails(capsys, argv, "could not build the calibration graph", "cam3")
    assert not out.parent.exists() or not any(out.parent.iterdir())


def test_bad_inputs_are_one_line(tiny_charuco, tmp_path, capsys):
    spec, scene, folder = tiny_charuco
    names = scene.rig.names
    out = tmp_path / "o" / "calib.toml"
    _fails(capsys, _args("charuco:5x4", folder, names, out), "--board")
    video = tmp_path / "cam1.mp4"
    video.write_bytes(b"not a video")
    argv = _args(spec, folder, names, out)
    argv[argv.index("--extrinsics") + 1] = str(video)
    _fails(capsys, argv, "cam1.mp4")
    _fails(capsys, _args("charuco:5x4:0.15:0.11:DICT_6X6_50", folder, names, out),
           "cam1", "DICT_4X4_50")  # fmt: skip
    assert not out.parent.exists()


def test_people_options_hand_over(capsys, tmp_path):
    out = tmp_path / "c.toml"
    _fails(capsys, ["calibrate", "--from-people", "--videos", "a.mp4", "--out", str(out)],
           "--calib", "intrinsics")  # fmt: skip
    assert not out.exists()
