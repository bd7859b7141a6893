"""A tiny rendered board set, shared by the calibration tests: three 480x360 cameras with
distortion, eight close-up views each and ten shared views (the first on the floor)."""

from __future__ import annotations

import pytest

from rmpl.calibration.boards import parse_board
from rmpl.calibration.render import make_scene, write_scene

pytest.importorskip("cv2")


def _tiny(kind: str):
    spec = "charuco:5x4:0.15:0.11:DICT_4X4_50" if kind == "charuco" else "checkerboard:6x4:0.15"
    board = parse_board(spec)
    scene = make_scene(
        board, cameras=3, size=(480, 360), focal=420.0, intrinsics_views=8,
        extrinsics_views=10, radius=2.0, height=1.3, seed=3,
    )  # fmt: skip
    return spec, scene


@pytest.fixture(scope="session")
def tiny_charuco(tmp_path_factory):
    """(board spec, Scene, folder with intrinsics/<cam>/, extrinsics/<cam>/, truth.toml)."""
    spec, scene = _tiny("charuco")
    folder = tmp_path_factory.mktemp("charuco")
    write_scene(scene, folder, blur=0.5, noise=1.0)
    return spec, scene, folder


@pytest.fixture(scope="session")
def tiny_checkerboard(tmp_path_factory):
    spec, scene = _tiny("checkerboard")
    folder = tmp_path_factory.mktemp("checkerboard")
    write_scene(scene, folder, blur=0.5, noise=1.0)
    return spec, scene, folder
