"""Tiny projects made from the embedded example (a 4-camera walk, 60 frames of 2D)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

WALK = Path(__file__).resolve().parents[2] / "src" / "rmpl" / "examples" / "walk"

#: Project options that keep a trial's run to about a second.
FAST = 'method = "triangulate"\nno-pictures = true\nformats = "npz"\npose2sim = "off"\n'


def make_trial(folder: Path, keypoints: bool = True) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if keypoints:
        shutil.copy(WALK / "keypoints.json", folder / "keypoints.json")
    return folder


@pytest.fixture
def walk_project(tmp_path: Path) -> Path:
    """rmpl's layout: calibration/ + two trials of 2D files, fast options at the top."""
    root = tmp_path / "project"
    (root / "calibration").mkdir(parents=True)
    shutil.copy(WALK / "calibration.toml", root / "calibration" / "calibration.toml")
    make_trial(root / "t1")
    make_trial(root / "t2")
    (root / "rmpl.toml").write_text(FAST)
    return root
