"""Synchronisation through a calibration: offsets of seconds between cameras at different
frame rates, the joint solve, and too little motion refused rather than guessed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.calibration.people_synth import moving_people, observe, ring_rig
from rmpl.calibration.sync import find_sync
from rmpl.calibration.sync_3d import _at, _View
from rmpl.errors import InputError


def _recording(offsets, fps, seconds, people=(1.8, 1.6), speed=1.0, seed=3, alone=False):
    """Camera v records ``seconds`` from true time 3 - o_v; ``speed`` < 1 slows the
    people's motion down (0: a static scene); ``alone``: the first camera sees only the
    first person."""
    rig = ring_rig(len(offsets), rng=seed)
    views = []
    for v, o in enumerate(offsets):
        times = 3.0 - o + np.arange(int(seconds * fps[v])) / fps[v]
        X = moving_people(speed * times, people, rng=seed + 10)
        X = X[:, :1] if alone and v == 0 else X
        views.append(observe(X, rig[[v]], noise=0.5, rng=seed + v)[0][:, 0])
    shape = (max(len(x) for x in views), len(offsets), len(people)) + views[0].shape[2:]
    kp = np.full(shape, np.nan)
    for v, x in enumerate(views):
        kp[: len(x), v, : x.shape[1]] = x
    return kp, rig


def test_offsets_of_seconds_between_cameras_at_different_rates():
    fps = np.array([25.0, 20.0, 30.0])
    offsets = np.array([0.0, 2.2, -1.73])  # 44 frames of cam1, -51.9 of cam2
    kp, rig = _recording(offsets, fps, seconds=5.0)
    sync = find_sync(kp, fps, rig.names, rig, max_offset=2.5)
    assert np.abs(sync.offset_frames - offsets * fps).max() < 0.25
    assert (sync.confidence > 0.5).all()  # z / (z + MIN_Z): every z above MIN_Z


def test_the_reference_sees_one_person_the_others_two():
    fps = np.full(3, 25.0)
    offsets = np.array([0.0, 0.6, -0.4])
    kp, rig = _recording(offsets, fps, seconds=4.0, alone=True)
    sync = find_sync(kp, fps, rig.names, rig, max_offset=1.0, fine=False)
    assert np.array_equal(np.round(sync.offset_frames), [0, 15, -10])


@pytest.mark.parametrize("people", [(1.8,), (1.8, 1.6)])
def test_too_little_motion_is_refused_in_one_line(people):
    """People standing still (the detector's noise is all that moves)."""
    fps = np.full(3, 25.0)
    kp, rig = _recording(np.array([0.0, 0.4, -0.2]), fps, 4.0, people, speed=0.0)
    with pytest.raises(InputError, match="enough motion") as e:
        find_sync(kp, fps, rig.names, rig, max_offset=1.0)
    assert "\n" not in str(e.value) and "undecided: cam1" in str(e.value)


def test_the_2d_is_interpolated_between_frames_per_person():
    T, P, J = 4, 2, 3
    norm = np.arange(T * P * J * 2, dtype=float).reshape(T, P, J, 2)
    nxt = np.tile([1, 0], (T, 1))  # the people swap places in every next frame
    nxt[-1] = -1
    view = _View(norm, nxt, np.zeros((T, P), int), 25.0, 1000.0)
    x = _at(view, np.array([0.25, 2.0, 3.5, -0.5]))
    assert np.allclose(x[0, 0], 0.75 * norm[0, 0] + 0.25 * norm[1, 1])
    assert np.allclose(x[1], norm[2])
    assert np.isnan(x[2:]).all()  # outside the recording


def test_run_sync_auto_finds_and_reports_the_offsets(tmp_path):
    from rmpl.cli import main
    from rmpl.io.calibration import save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints

    fps = np.full(3, 30.0)
    kp, rig = _recording(np.array([0.0, 6 / 30, -4 / 30]), fps, seconds=2.5, people=(1.75,))
    save_rig(rig, tmp_path / "calib.toml")
    scores = np.isfinite(kp[..., 0]) * 0.9
    save_keypoints(Keypoints2D(kp, scores, "coco17", rig.names, None, 30.0), tmp_path / "kp.npz")
    args = ["run", "--calib", str(tmp_path / "calib.toml"), "--keypoints",
            str(tmp_path / "kp.npz"), "--method", "triangulate", "--no-pictures",
            "--sync", "auto", "--out", str(tmp_path / "run")]  # fmt: skip
    assert main(args) in (0, 3)
    sync = json.loads((tmp_path / "run" / "report.json").read_text())["sync"]
    assert sync["source"] == "auto"
    assert [round(c["offset_frames"]) for c in sync["cameras"].values()] == [0, 6, -4]
