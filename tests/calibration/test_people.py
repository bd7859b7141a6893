"""Calibration from people: known rigs recovered from synthetic people, the given
extrinsics never read, the scale sources, --refine, and bad input in one line."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from rmpl.calibration.people import calibrate_from_people, similarity
from rmpl.calibration.people_report import run_cli
from rmpl.calibration.people_synth import moving_people, observe, ring_rig
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, rodrigues


def _scene(views=3, heights=(1.75,), frames=60, seed=2):
    rig = ring_rig(views, rng=seed, distortion=True)
    X = moving_people(np.arange(frames) / 20, heights, rng=seed + 1)
    kp, sc = observe(X, rig, noise=1.0, rng=seed)
    return rig, kp, sc


def _errors(found: Rig, truth: Rig):
    """Per camera (degrees, metres) after a similarity alignment, and its scale."""
    s, R, t = similarity(found.centers, truth.centers)
    ang = [
        np.degrees(np.arccos(np.clip((np.trace(f.R @ R.T @ g.R.T) - 1) / 2, -1, 1)))
        for f, g in zip(found, truth, strict=True)
    ]
    d = np.linalg.norm(s * found.centers @ R.T + t - truth.centers, axis=-1)
    return np.array(ang), d, s


def _garbage(rig: Rig, seed=7) -> Rig:
    rng = np.random.default_rng(seed)
    return Rig(
        tuple(
            Camera(
                c.K, rodrigues(rng.normal(size=3)), rng.normal(size=3) * 50, c.dist, c.size, c.name
            )
            for c in rig
        )
    )


@pytest.mark.parametrize("heights", [(1.75,), (1.8, 1.6)])
def test_known_rig_recovered(heights):
    rig, kp, sc = _scene(heights=heights)
    cal = calibrate_from_people(kp, sc, rig, max_frames=40)
    ang, d, s = _errors(cal.rig, rig)
    assert ang.max() < 0.3 and d.max() < 0.03
    assert abs(s - 1) < 0.15  # the adult prior on statures of 1.6-1.8 m
    assert (cal.rms < 3.0).all() and len(cal.people) == len(heights)
    assert np.abs(cal.rig.centers[:, 2]).min() > 1.0  # z up: the cameras above the floor


def test_given_extrinsics_are_never_read():
    rig, kp, sc = _scene()
    a = calibrate_from_people(kp, sc, rig, max_frames=30)
    b = calibrate_from_people(kp, sc, _garbage(rig), max_frames=30)
    assert np.array_equal(a.rig.R, b.rig.R) and np.array_equal(a.rig.t, b.rig.t)


def test_scale_from_height_and_from_camera_distance():
    rig, kp, sc = _scene()
    cal = calibrate_from_people(kp, sc, rig, height=1.75, max_frames=30)
    assert abs(_errors(cal.rig, rig)[2] - 1) < 0.06 and "--height" in cal.scale_source
    d = float(np.linalg.norm(rig.centers[0] - rig.centers[2]))
    cal = calibrate_from_people(kp, sc, rig, camera_distance=("cam0", "cam2", d), max_frames=30)
    assert abs(_errors(cal.rig, rig)[2] - 1) < 0.01


def test_refine_corrects_a_bumped_camera():
    rig, kp, sc = _scene(views=4)
    bumped = list(rig)
    c = bumped[1]
    bumped[1] = Camera(
        c.K, rodrigues(np.array([0.0, 0.05, 0.0])) @ c.R, c.t + [0.2, 0, 0], c.dist, c.size, c.name
    )
    cal = calibrate_from_people(kp, sc, rig, start=Rig(tuple(bumped)), max_frames=30)
    ang, d, s = _errors(cal.rig, rig)
    assert ang.max() < 0.3 and d.max() < 0.03
    moved = {m["camera"]: m for m in cal.moved}
    assert moved["cam1"]["rotation_deg"] > 2.0
    assert max(moved[c]["rotation_deg"] for c in ("cam0", "cam2", "cam3")) < 0.3


def test_one_camera_is_refused():
    rig, kp, sc = _scene()
    with pytest.raises(InputError, match="two or more cameras"):
        calibrate_from_people(kp[:, :1], sc[:, :1], rig[[0]])


def test_no_person_in_a_view_is_refused():
    rig, kp, sc = _scene()
    kp[:, 1], sc[:, 1] = np.nan, 0.0
    with pytest.raises(InputError, match="view cam1"):
        calibrate_from_people(kp, sc, rig)


def test_intrinsics_that_do_not_fit_the_images_are_refused():
    rig, kp, sc = _scene()
    small = Rig(
        tuple(
            Camera(
                c.K / [[2], [2], [1]], c.R, c.t, c.dist, (c.size[0] // 2, c.size[1] // 2), c.name
            )
            for c in rig
        )
    )
    with pytest.raises(InputError, match="fit the images"):
        calibrate_from_people(kp, sc, small)


def test_run_cli_writes_calibration_and_report(tmp_path):
    from rmpl.io.calibration import load_rig, save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints

    rig, kp, sc = _scene()
    save_rig(_garbage(rig), tmp_path / "intrinsics.toml")
    save_keypoints(Keypoints2D(kp, sc, "coco17", rig.names, None, 20.0), tmp_path / "kp.npz")
    args = argparse.Namespace(
        from_people=True,
        refine=None,
        calib=str(tmp_path / "intrinsics.toml"),
        keypoints=[str(tmp_path / "kp.npz")],
        videos=None,
        height=None,
        camera_distance=None,
        max_frames=30,
        format=None,
        out=str(tmp_path / "out" / "calib.toml"),
    )
    assert run_cli(args) == 0
    ang, d, _ = _errors(load_rig(tmp_path / "out" / "calib.toml"), rig)
    assert ang.max() < 0.3
    doc = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert len(doc["cameras"]) == 3 and "adult body prior" in doc["scale"]["source"]
    assert "reprojection RMS" in (tmp_path / "out" / "calibration.md").read_text()
    args.camera_distance = ["cam0", "nope", "2.0"]
    with pytest.raises(InputError, match="--camera-distance"):
        run_cli(args)


def test_cameras_not_started_together_calibrate_with_rmpl_sync_offsets(tmp_path):
    from rmpl.calibration.sync import Sync, write_sync
    from rmpl.io.calibration import load_rig, save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints

    rig = ring_rig(3, rng=2, distortion=True)
    X = moving_people(np.arange(64) / 20, (1.75,), rng=3)
    kp, sc = observe(X, rig, noise=1.0, rng=2)
    late = 4  # cam2 started 4 frames late: its frame t is everyone's t + 4
    kp = np.concatenate([kp[:60, :2], kp[late : 60 + late, 2:]], 1)
    sc = np.concatenate([sc[:60, :2], sc[late : 60 + late, 2:]], 1)
    save_rig(_garbage(rig), tmp_path / "intrinsics.toml")
    save_keypoints(Keypoints2D(kp, sc, "coco17", rig.names, None, 20.0), tmp_path / "kp.npz")
    write_sync(Sync(rig.names, np.full(3, 20.0), np.array([0, 0, -late / 20]), np.ones(3)),
               tmp_path / "sync.json")  # fmt: skip
    args = argparse.Namespace(
        from_people=True, refine=None, calib=str(tmp_path / "intrinsics.toml"),
        keypoints=[str(tmp_path / "kp.npz")], videos=None, height=None,
        camera_distance=None, max_frames=40, format=None, sync=None,
        out=str(tmp_path / "out" / "calib.toml"),
    )  # fmt: skip
    with pytest.raises(InputError, match="view cam2.*--sync"):
        run_cli(args)  # as recorded: cam2 disagrees with the others
    assert not (tmp_path / "out" / "calib.toml").exists()
    args.sync = str(tmp_path / "sync.json")
    assert run_cli(args) == 0
    assert _errors(load_rig(args.out), rig)[0].max() < 0.3
    doc = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert doc["sync"]["cameras"]["cam2"]["offset_frames"] == -late


def test_a_camera_the_others_disagree_with_is_refused_in_one_line():
    rig = ring_rig(3, rng=2, distortion=True)
    X = moving_people(np.arange(70) / 20, (1.75,), rng=3)
    kp, sc = observe(X, rig, noise=1.0, rng=2)
    kp = np.concatenate([kp[:60, :2], kp[10:, 2:]], 1)  # cam2 half a second late
    with pytest.raises(InputError, match="view cam2.*agree with the other cameras"):
        calibrate_from_people(kp, sc[:60], rig, max_frames=40)


def test_an_unreliable_camera_is_written_warned_and_exits_3(tmp_path, monkeypatch):
    import rmpl.calibration.people as people
    from rmpl.io.calibration import save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints

    rig, kp, sc = _scene()
    save_rig(_garbage(rig), tmp_path / "intrinsics.toml")
    save_keypoints(Keypoints2D(kp, sc, "coco17", rig.names, None, 20.0), tmp_path / "kp.npz")
    args = argparse.Namespace(
        from_people=True, refine=None, calib=str(tmp_path / "intrinsics.toml"),
        keypoints=[str(tmp_path / "kp.npz")], videos=None, height=None, camera_distance=None,
        max_frames=30, format=None, sync=None, out=str(tmp_path / "calib.toml"),
    )  # fmt: skip
    assert run_cli(args) == 0  # well placed: every centre within 5% of its distance
    doc = json.loads((tmp_path / "calibration.json").read_text())
    rel = [c["centre_sd_of_distance"] for c in doc["cameras"]]
    assert max(rel) < people.UNRELIABLE_SD and doc["warnings"] == []
    monkeypatch.setattr(people, "UNRELIABLE_SD", min(r for r in rel if r > 0) / 2)
    assert run_cli(args) == 3
    doc = json.loads((tmp_path / "calibration.json").read_text())
    assert len(doc["warnings"]) == sum(r > 0 for r in rel)  # the gauge camera is exact
    assert "WARNING: camera" in (tmp_path / "calibration.md").read_text()
    assert (tmp_path / "calib.toml").is_file()


def test_a_static_scene_is_refused_in_one_line():
    rig = ring_rig(3, rng=2)
    X = moving_people(np.zeros(60), (1.75,), rng=3)  # one instant, sixty frames
    kp, sc = observe(X, rig, noise=1.0, rng=2)
    with pytest.raises(InputError, match="people who move"):
        calibrate_from_people(kp, sc, rig, max_frames=40)
