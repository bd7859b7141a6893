"""Synchronisation from motion: known offsets recovered on synthetic rigs, sync.json, the
2D put on the reference's clock, and bad input refused in one line."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from rmpl.calibration.people_synth import moving_people, observe, ring_rig
from rmpl.calibration.sync import (
    Sync,
    apply_sync,
    find_sync,
    link_people,
    read_sync,
    write_sync,
)
from rmpl.errors import InputError

FPS = np.array([30.0, 30.0, 25.0])


def _recording(offsets, fps=FPS, n=90, people=(1.8, 1.6), seed=5, still=False):
    """Each camera records n frames; camera v's frame f is at true time 2 - o_v + f / fps_v."""
    rig = ring_rig(len(offsets), rng=1)
    views = []
    for v, o in enumerate(offsets):
        times = 2.0 - o + np.arange(n) / fps[v]
        X = moving_people(np.zeros(n) if still else times, people, rng=seed)
        views.append(observe(X, rig[[v]], noise=0.5, rng=v)[0][:, 0])
    return np.stack(views, 1), rig


def test_whole_frame_offsets_found_exactly():
    offsets = np.array([0.0, 20 / 30, -15 / 25])
    kp, rig = _recording(offsets)
    sync = find_sync(kp, FPS, rig.names, rig, max_offset=1.0, fine=False)
    assert np.array_equal(np.round(sync.offset_frames), [0, 20, -15])
    assert (sync.confidence > 0).all()


def test_fractions_of_a_frame():
    offsets = np.array([0.0, 10.4 / 30, -7.7 / 25])
    kp, rig = _recording(offsets)
    sync = find_sync(kp, FPS, rig.names, rig, max_offset=0.6)
    assert sync.method == "3d-fine"
    assert np.abs(sync.offset_frames - offsets * FPS).max() < 0.25


def test_given_offsets_put_the_2d_on_the_reference_clock():
    from rmpl.io.keypoints import Keypoints2D

    offsets = np.array([0.0, 5 / 30, -3.5 / 25])
    kp, rig = _recording(offsets)
    sync = Sync(rig.names, FPS, offsets, np.ones(3))
    aligned = apply_sync(Keypoints2D(kp, np.isfinite(kp[..., 0]) * 0.9, "coco17",
                                     rig.names, None, 30.0), sync)  # fmt: skip
    truth, _ = _recording(np.zeros(3), fps=np.full(3, 30.0))
    for v in range(3):
        a, b = link_people(aligned.keypoints[:, v]), link_people(truth[:, v])
        d = np.linalg.norm(a[:, :, None] - b[:, None], axis=-1)  # (T, Qa, Qb, J)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # tracks absent in a frame
            best = np.nanmin(np.nanmedian(d, -1), -1)
        best = best[np.isfinite(best)]
        assert len(best) > 50 and np.median(best) < 2.0  # pixels (0.5 px noise)


def test_sync_file_round_trip(tmp_path):
    sync = Sync(["a", "b"], np.array([30.0, 25.0]), np.array([0.0, -1.24]), np.array([1, 0.8]))
    back = read_sync(write_sync(sync, tmp_path / "sync.json"))
    assert back.views == ["a", "b"] and np.allclose(back.offsets, sync.offsets)
    assert back.to_dict()["cameras"]["b"]["offset_frames"] == -31


def test_a_static_scene_is_refused():
    kp, rig = _recording(np.zeros(3), still=True)
    with pytest.raises(InputError, match="enough motion"):
        find_sync(kp, FPS, rig.names, rig, max_offset=1.0)


def test_one_camera_is_refused():
    kp, rig = _recording(np.zeros(1), fps=FPS[:1])
    with pytest.raises(InputError, match="two or more cameras"):
        find_sync(kp, 30.0, rig.names, rig)


def test_a_view_without_people_is_refused():
    kp, rig = _recording(np.zeros(3))
    kp[:, 2] = np.nan
    with pytest.raises(InputError, match="view cam2"):
        find_sync(kp, FPS, rig.names, rig)


def test_a_bad_sync_file_is_one_clear_line(tmp_path):
    p = tmp_path / "sync.json"
    p.write_text('{"format": "something else"}')
    with pytest.raises(InputError, match="format"):
        read_sync(p)


def test_command_writes_sync_json(tmp_path):
    from rmpl.cli import main
    from rmpl.io.calibration import save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints

    offsets = np.array([0.0, 12 / 30, -9 / 30])
    kp, rig = _recording(offsets, fps=np.full(3, 30.0))
    save_rig(rig, tmp_path / "calib.toml")
    save_keypoints(Keypoints2D(kp, np.isfinite(kp[..., 0]) * 0.9, "coco17", rig.names,
                               None, 30.0), tmp_path / "kp.npz")  # fmt: skip
    out = tmp_path / "sync.json"
    args = [
        "sync",
        "--calib",
        str(tmp_path / "calib.toml"),
        "--keypoints",
        str(tmp_path / "kp.npz"),
        "--out",
        str(out),
        "--max-offset",
        "0.8",
        "--coarse",
    ]
    assert main(args) == 0
    assert np.array_equal(np.round(read_sync(out).offset_frames), [0, 12, -9])
    assert main(["sync", "--keypoints", str(tmp_path / "kp.npz"), "--fps", "30", "40",
                 "--out", str(out)]) == 2  # fmt: skip


def test_run_applies_a_sync_file_and_reports_it(tmp_path):
    from rmpl.cli import main
    from rmpl.io.calibration import save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints

    offsets = np.array([0.0, 4 / 30, -3 / 30])
    kp, rig = _recording(offsets, fps=np.full(3, 30.0), n=40, people=(1.75,))
    save_rig(rig, tmp_path / "calib.toml")
    save_keypoints(Keypoints2D(kp, np.isfinite(kp[..., 0]) * 0.9, "coco17", rig.names,
                               None, 30.0), tmp_path / "kp.npz")  # fmt: skip
    write_sync(Sync(rig.names, np.full(3, 30.0), offsets, np.ones(3)), tmp_path / "sync.json")
    args = ["run", "--calib", str(tmp_path / "calib.toml"), "--keypoints",
            str(tmp_path / "kp.npz"), "--method", "triangulate", "--no-pictures",
            "--sync", str(tmp_path / "sync.json"), "--out", str(tmp_path / "run")]  # fmt: skip
    assert main(args) in (0, 3)
    report = json.loads((tmp_path / "run" / "report.json").read_text())
    assert report["sync"]["cameras"]["cam1"]["offset_frames"] == 4
    assert "Synchronisation" in (tmp_path / "run" / "report.md").read_text()


def test_a_sync_file_named_like_the_2d_files_applies_by_order():
    from rmpl.io.keypoints import Keypoints2D

    offsets = np.array([0.0, 5 / 30, -3.5 / 25])
    kp, rig = _recording(offsets)
    sync = Sync(["cam01", "cam02", "cam03"], FPS, offsets, np.ones(3))  # the 2D files' names
    kp2d = Keypoints2D(kp, np.isfinite(kp[..., 0]) * 0.9, "coco17", rig.names, None, 30.0)
    by_order = apply_sync(kp2d, sync)
    by_name = apply_sync(kp2d, Sync(rig.names, FPS, offsets, np.ones(3)))
    assert np.array_equal(by_order.keypoints, by_name.keypoints, equal_nan=True)
    with pytest.raises(InputError, match="views named like the cameras"):
        apply_sync(kp2d, Sync(["cam01", "cam02"], FPS[:2], offsets[:2], np.ones(2)))


def test_without_a_calibration_chance_correlations_are_refused_not_guessed():
    offsets = np.array([0.0, 12 / 30, -9 / 25])
    short, rig = _recording(offsets, n=40)  # a second and a half of smooth motion
    with pytest.raises(InputError, match="standard errors"):
        find_sync(short, FPS, rig.names, None, max_offset=1.0)
