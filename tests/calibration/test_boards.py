"""Board specs and files, corner detection (plain, inverted, advice) and one camera's lens."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.calibration.boards import parse_board
from rmpl.calibration.detect import detect, diagnose
from rmpl.calibration.frames import read_views
from rmpl.calibration.intrinsics import calibrate_intrinsics
from rmpl.calibration.render import make_scene, render_board
from rmpl.errors import InputError


def test_specs_parse():
    b = parse_board("checkerboard:4x7:0.06")
    assert (b.kind, b.inner, b.square) == ("checkerboard", (4, 7), 0.06)
    assert np.allclose(b.points[5], [0.06, 0.06, 0.0])  # row 1, column 1
    c = parse_board("charuco:5x7:0.04:0.03:dict_5x5_100")
    assert (c.inner, c.dictionary, c.marker) == ((4, 6), "DICT_5X5_100", 0.03)
    assert parse_board("charuco:5x7:0.04:0.03").dictionary == "DICT_4X4_50"


@pytest.mark.parametrize(
    "spec, says",
    [
        ("checkerboard:4by7:0.06", "COLSxROWS"),
        ("checkerboard:4x7:60", "metres"),
        ("charuco:5x7:0.04", "charuco:COLSxROWS"),
        ("charuco:5x7:0.04:0.05", "smaller than its square"),
        ("charuco:5x7:0.04:0.03:DICT_9X9_50", "ArUco dictionary"),
        ("checkerboard:1x7:0.06", "2x2 inner corners"),
        ("circles:4x7:0.06", "checkerboard:COLSxROWS"),
    ],
)
def test_bad_specs_are_one_line(spec, says):
    with pytest.raises(InputError, match=says) as e:
        parse_board(spec)
    assert "\n" not in str(e.value)


def test_board_files(tmp_path):
    cali = tmp_path / "charuco.toml"
    cali.write_text(
        'columns = 4\nrows = 5\ndictionary = "DICT_4X4_1000"\naruco_scale = 0.75\n'
        "square_size_override_cm = 5.4\ninverted = true\n"
    )
    b = parse_board(str(cali))
    assert (b.cols, b.rows, b.dictionary, b.inverted) == (4, 5, "DICT_4X4_1000", True)
    assert b.square == pytest.approx(0.054) and b.marker == pytest.approx(0.0405)
    ani = tmp_path / "config.toml"
    ani.write_text(
        '[calibration]\nboard_type = "charuco"\nboard_size = [10, 7]\nboard_marker_bits = 4\n'
        "board_marker_dict_number = 50\nboard_marker_length = 18.75\n"
        "board_square_side_length = 25\n"
    )
    a = parse_board(str(ani))
    assert (a.cols, a.rows, a.square, a.marker) == (10, 7, 0.025, 0.01875)
    p2s = tmp_path / "Config.toml"
    p2s.write_text(
        "[calibration.calculate.intrinsics]\nintrinsics_corners_nb = [4, 7]\n"
        "intrinsics_square_size = 60\n"
    )
    assert parse_board(str(p2s)).spec() == "checkerboard:4x7:0.06"
    bad = tmp_path / "other.toml"
    bad.write_text("x = 1\n")
    with pytest.raises(InputError, match="caliscope"):
        parse_board(str(bad))


def _view(spec: str, inverted: bool = False):
    from dataclasses import replace

    board = parse_board(spec)
    scene = make_scene(board, cameras=1, size=(480, 360), focal=420.0, intrinsics_views=1, seed=1)
    drawn = replace(board, inverted=inverted)
    image = render_board(drawn, scene.rig[0], scene.intrinsics[0][0], noise=1.0)
    return board, scene, image


@pytest.mark.parametrize("spec", ["checkerboard:6x4:0.05", "charuco:5x4:0.06:0.045"])
@pytest.mark.parametrize("inverted", [False, True])
def test_detection_finds_the_true_corners(spec, inverted):
    board, scene, image = _view(spec, inverted)
    found = detect(image, board)
    assert found is not None and len(found) >= board.min_corners
    R, t = scene.intrinsics[0][0]
    truth = scene.rig[0].project(board.points[found.ids] @ R.T + t)
    err = np.linalg.norm(found.corners - truth, axis=1)
    if board.kind == "checkerboard" and err.mean() > 5:  # the same board turned 180 degrees
        err = np.linalg.norm(found.corners[::-1] - truth, axis=1)
    assert np.median(err) < 0.3


def test_advice_for_squares_given_as_corners():
    board, _, image = _view("checkerboard:6x4:0.05")
    wrong = parse_board("checkerboard:7x5:0.05")
    assert detect(image, wrong) is None
    assert "6x4 inner corners" in diagnose([image], wrong)


def test_advice_for_the_wrong_dictionary():
    board, _, image = _view("charuco:5x4:0.06:0.045")
    wrong = parse_board("charuco:5x4:0.06:0.045:DICT_6X6_50")
    assert detect(image, wrong) is None
    assert "DICT_4X4_50" in diagnose([image], wrong)


@pytest.mark.parametrize("which", ["tiny_charuco", "tiny_checkerboard"])
def test_intrinsics_of_the_tiny_set(which, request):
    spec, scene, folder = request.getfixturevalue(which)
    board = parse_board(spec)
    for cam in scene.rig:
        views = read_views(folder / "intrinsics" / cam.name, board, cam.name, progress=False)
        lens = calibrate_intrinsics(views.named(), board, views.size)
        # 8 views of 480x360: twice the full-size targets (0.3 %, 3 px, 0.3 px)
        assert abs(lens.K[0, 0] / cam.K[0, 0] - 1) < 0.015
        assert np.abs(lens.K[:2, 2] - cam.K[:2, 2]).max() < 3.0
        assert lens.rms < 0.6 and set(lens.used).isdisjoint(lens.dropped)


def test_too_few_images_and_no_board(tmp_path, tiny_charuco):
    spec, scene, folder = tiny_charuco
    board = parse_board(spec)
    views = read_views(folder / "intrinsics" / "cam1", board, "cam1", progress=False)
    few = dict(list(views.named().items())[:2])
    with pytest.raises(InputError, match="at least 4 images"):
        calibrate_intrinsics(few, board, views.size, camera="cam1")
    import cv2

    empty = tmp_path / "camX"
    empty.mkdir()
    cv2.imwrite(str(empty / "0.png"), np.full((120, 160), 128, np.uint8))
    with pytest.raises(InputError, match="camera camX.*none of 1"):
        read_views(empty, board, "camX", progress=False)
