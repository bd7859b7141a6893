"""rmpl generate: config validation (always), and a tiny end-to-end generation with anny,
the EGL renderer and MediaPipe (skipped when they or anny's cache are absent): projection
accuracy, resume after an interrupted run, --stats, Ray. The same for sequences
(``sequence_frames``), driven by a made-up motion bank so they need no motion data."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.synth.generate import (
    SEQUENCE_FORMAT,
    GenerateConfig,
    MotionBank,
    draw_window,
    follow_root,
    generate,
    list_shards,
    load_motion_bank,
    occlude,
    save_motion_bank,
    shard_path,
)
from tests.conftest import synth_ready

# Stated accuracy: on 400x400 renders (h36m cameras scaled to fit, person ~150-250 px tall),
# MediaPipe's confident keypoints (score > 0.5) lie within a median of 10 px of the mesh's
# regressed COCO-17 joints projected by the stored cameras (3 px is typical here). A wrong
# camera convention, axis or a half-pixel-scaled K would be off by tens of pixels.
MEDIAN_PX = 10.0

TINY = {
    "poses": "random",
    "num_meshes": 3,
    "views": 4,
    "shard_size": 1,
    "batch_size": 1,
    "camera_preset": "h36m",
    "image_size": [400, 400],
    "seed": 7,
}


def test_bad_config_keys_are_clear(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('num_mehses = 3\nposes = "random"\n')
    with pytest.raises(InputError, match=r"bad\.toml: field 'num_mehses': expected one of"):
        GenerateConfig.from_toml(bad)
    bad.write_text("views = 'many'\n")
    with pytest.raises(InputError, match="field 'views': expected a int"):
        GenerateConfig.from_toml(bad)
    bad.write_text('camera_preset = "moon"\n')
    with pytest.raises(InputError, match="camera_preset"):
        GenerateConfig.from_toml(bad)
    ok = tmp_path / "ok.toml"
    ok.write_text("views = 3\nimage_size = [320, 240]\n")
    cfg = GenerateConfig.from_toml(ok, ["num_meshes=5", "poses=/some/where"])
    assert (cfg.views, cfg.image_size, cfg.num_meshes, cfg.poses) == (
        3,
        (320, 240),
        5,
        "/some/where",
    )
    assert cfg.num_shards == 1


def test_cli_reports_bad_config(tmp_path, capsys):
    from rmpl.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text("nope = 1\n")
    assert main(["generate", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "nope" in err and "Traceback" not in err


def test_occlude_pastes_black_squares():
    rng = np.random.default_rng(0)
    images = [np.full((100, 120, 3), 200, np.uint8)]
    pts = np.array([[[50.0, 40.0], [5.0, 5.0], [np.nan, np.nan]]])
    hit = occlude(images, pts, 1.0, 20, rng)
    assert hit.all()
    im = images[0]
    assert (im[30:50, 40:60] == 0).all() and im[55, 70].tolist() == [200, 200, 200]
    assert (im[0:15, 0:15] == 0).all()  # clipped at the border
    assert occlude([im.copy()], pts, 0.0, 20, rng).sum() == 0


def _needs_synth():
    synth_ready("anny", "moderngl", "mediapipe")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    _needs_synth()
    out = tmp_path_factory.mktemp("mhp") / "run"
    summary = generate(GenerateConfig.from_dict(TINY), out, progress=False)
    return out, summary


def test_tiny_generation_projects_onto_detections(tiny_run):
    out, summary = tiny_run
    assert summary["shards"] == 3 and summary["meshes"] == 3 and summary["views"] == 12
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "complete" and manifest["skeleton"] == "coco17"
    assert manifest["units"]["3d"] == "metres" and manifest["detector"] == "mediapipe"
    # A single-frame set's manifest is the one written before sequences existed.
    assert manifest["format"] == "rmpl.mhp.v1" and "sequence_frames" not in manifest["config"]
    from rmpl.data.mhp import load_mhp
    from rmpl.geometry.camera import project

    d = load_mhp(out)
    assert d["keypoints"].shape == (3, 4, 17, 2) and d["joints3d"].shape == (3, 17, 3)
    assert np.all(d["size"] == [400, 400])
    # The stored cameras reproduce the stored projections of the 3D joints.
    uv = project(
        d["joints3d"][:, None].astype(float),
        d["K"][:, :, None],
        d["R"][:, :, None],
        d["t"][:, :, None],
    )
    assert np.allclose(uv, d["projected"], atol=1e-2)
    detected = d["scores"].max(-1) > 0
    assert detected.mean() >= 2 / 3, detected
    ok = d["scores"] > 0.5
    err = np.linalg.norm(d["keypoints"] - uv, axis=-1)[ok]
    assert ok.sum() >= 50 and np.median(err) < MEDIAN_PX, np.median(err)


def test_resume_regenerates_only_missing_shards(tiny_run, tmp_path):
    src, _ = tiny_run
    out = tmp_path / "run"
    shutil.copytree(src, out)
    before = {p.name: p.stat().st_mtime_ns for p in list_shards(out)}
    with np.load(shard_path(out, 1)) as z:
        original = z["joints3d"].copy()
    shard_path(out, 1).unlink()  # as if the run was killed while writing shard 1
    leftover = out / ".shard_00001.npz.abc123.part.npz"  # atomic_path's temp file
    leftover.write_bytes(b"partial")
    summary = generate(GenerateConfig.from_dict(TINY), out, progress=False)
    after = {p.name: p.stat().st_mtime_ns for p in list_shards(out)}
    assert sorted(after) == sorted(before)
    assert after["shard_00000.npz"] == before["shard_00000.npz"]
    assert after["shard_00002.npz"] == before["shard_00002.npz"]
    assert summary["this_run"]["views"] == 4 and summary["shards"] == 3
    with np.load(shard_path(out, 1)) as z:
        assert np.array_equal(z["joints3d"], original)  # seeded by (seed, shard)
    # A different config in the same directory is refused, naming the field.
    with pytest.raises(InputError, match="field 'views'"):
        generate(GenerateConfig.from_dict({**TINY, "views": 5}), out, progress=False)


def test_stats_runs_and_fits_noise(tiny_run, tmp_path, capsys):
    from rmpl.cli import main
    from rmpl.synth.noise import NoiseConfig

    out, _ = tiny_run
    noise_file = tmp_path / "noise.toml"
    assert main(["generate", "--stats", str(out), "--noise-out", str(noise_file)]) == 0
    text = capsys.readouterr().out
    assert "| left_wrist |" in text and "Fitted NoiseConfig" in text
    import tomllib

    table = tomllib.loads(noise_file.read_text())["noise"]
    cfg = NoiseConfig.from_dict(table)
    assert len(cfg.joint_sigma) == 17 and all(0 < s < 0.2 for s in cfg.joint_sigma)
    assert table == json.loads(noise_file.with_suffix(".json").read_text())


@pytest.mark.shared
def test_generate_from_motion_holds_out_subjects(shared_data, tmp_path):
    _needs_synth()
    motion = shared_data / "cmu_mocap"
    if not motion.is_dir():
        pytest.skip(f"{motion} not found")
    cfg = GenerateConfig.from_dict(
        {
            **TINY,
            "poses": str(motion),
            "subjects": ["12", "03"],
            "exclude_subjects": ["03"],
            "num_meshes": 2,
            "views": 2,
            "shard_size": 2,
            "batch_size": 1,  # two batches in the shard: the second must stay paired too
            "image_size": [320, 240],
            "occlusion_rate": 0.5,
        }
    )
    generate(cfg, tmp_path, progress=False)
    with np.load(shard_path(tmp_path, 0)) as z:
        assert set(z["subject"].tolist()) == {"12"}
        assert all("/12/" in c for c in z["clip"]) and (z["frame"] >= 0).all()
        assert 0 < z["occluded"].mean() < 1
        occluded = {k: z[k] for k in ("joints3d", "K", "R", "t", "projected")}
    # Without squares: the same meshes and cameras (the occlusion experiment is paired).
    clean = tmp_path / "clean"
    generate(dataclasses.replace(cfg, occlusion_rate=0.0), clean, progress=False)
    with np.load(shard_path(clean, 0)) as z:
        for k, v in occluded.items():
            np.testing.assert_array_equal(z[k], v, err_msg=k)
        assert not z["occluded"].any()
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert set(manifest["pose_bank"]["subjects"]) == {"12"}


def test_generate_on_local_ray(tmp_path):
    pytest.importorskip("ray", reason="ray not installed (pip install 'rmpl[ray]')")
    _needs_synth()
    import ray

    cfg = GenerateConfig.from_dict({**TINY, "num_meshes": 2, "views": 2, "image_size": [256, 256]})
    bank = save_motion_bank(tmp_path / "walk.npz", _walk_bank())
    seq = GenerateConfig.from_dict({**TINY_SEQ, "poses": str(bank), "sequence_frames": 3})
    try:
        summary = generate(cfg, tmp_path / "single", workers=2, ray_address="local",
                           progress=False)  # fmt: skip
        # Sequences run through the same Ray task.
        seq_summary = generate(seq, tmp_path / "seq", workers=2, ray_address="local",
                               progress=False)  # fmt: skip
    finally:
        ray.shutdown()
    assert summary["shards"] == 2 and summary["views"] == 4
    assert [p.name for p in list_shards(tmp_path / "single")] == [
        "shard_00000.npz",
        "shard_00001.npz",
    ]
    assert seq_summary["sequences"] == 2 and seq_summary["views"] == 2 * 3 * 2
    with np.load(shard_path(tmp_path / "seq", 1)) as z:
        assert z["keypoints"].shape == (1, 3, 2, 17, 2)


# ------------------------------------------------------------------------------ sequences

# A standing COCO-17 person, z up, facing -y, metres (legs 0.45 + 0.42 m).
_STANDING = np.array(
    [
        [0.0, -0.1, 1.6], [0.03, -0.08, 1.63], [-0.03, -0.08, 1.63], [0.07, 0.0, 1.6],
        [-0.07, 0.0, 1.6], [0.18, 0.0, 1.45], [-0.18, 0.0, 1.45], [0.3, 0.0, 1.2],
        [-0.3, 0.0, 1.2], [0.4, 0.0, 1.0], [-0.4, 0.0, 1.0], [0.1, 0.0, 0.95],
        [-0.1, 0.0, 0.95], [0.1, 0.0, 0.5], [-0.1, 0.0, 0.5], [0.1, 0.0, 0.08],
        [-0.1, 0.0, 0.08],
    ]
)  # fmt: skip
WALK_SPEED = 1.0  # m/s along +x


def _walk_bank(lengths=(40, 60), subjects=("01", "03"), fps=120.0) -> MotionBank:
    """A made-up motion bank: one segment per clip; anny's reference pose with the thighs
    swinging +-20 degrees about x, the mocap root walking along +x at WALK_SPEED."""
    from rmpl.geometry.camera import rodrigues
    from rmpl.synth.retarget import DRIVEN

    names = [b for b, _ in DRIVEN]
    rot, joints = [], []
    for n in lengths:
        r = np.broadcast_to(np.eye(3), (n, len(DRIVEN), 3, 3)).copy()
        swing = np.radians(20) * np.sin(2 * np.pi * np.arange(n) / fps)  # one stride a second
        for side, sign in ((".L", 1), (".R", -1)):
            turn = rodrigues(np.stack([sign * swing, 0 * swing, 0 * swing], -1))  # (n, 3, 3)
            for bone in ("upperleg01", "lowerleg01", "foot"):
                r[:, names.index(bone + side)] = turn
        rot.append(r.astype(np.float32))
        path = np.stack([WALK_SPEED * np.arange(n) / fps, 0 * np.arange(n), 0 * np.arange(n)], -1)
        joints.append((_STANDING + path[:, None]).astype(np.float32))
    length = np.array(lengths, np.int64)
    C = len(lengths)
    return MotionBank(
        np.concatenate(rot),
        np.concatenate(joints),
        np.cumsum(length) - length,
        length,
        np.zeros(C, np.int64),
        np.arange(C),
        np.array([f"walk/{s}_01.bvh" for s in subjects]),
        np.array(subjects),
        np.full(C, fps),
        np.zeros((C, len(DRIVEN), 3), np.float32),
    )


TINY_SEQ = {
    "num_meshes": 2,  # sequences
    "views": 2,
    "shard_size": 1,
    "camera_preset": "h36m",
    "image_size": [320, 320],
    "sequence_frames": 4,
    "sequence_fps": [20, 40],
    "subjects": ["03"],
    "perturb_deg": 0.0,
    "seed": 3,
}


@pytest.mark.parametrize(
    "override, field",
    [
        ({"sequence_frames": -1}, "sequence_frames"),
        ({"sequence_frames": 1.5}, "sequence_frames"),
        ({"sequence_fps": [60, 10]}, "sequence_fps"),
        ({"sequence_fps": [0, 10]}, "sequence_fps"),
        ({"sequence_fps": [10]}, "sequence_fps"),
        ({"sequence_fps": [10, "x"]}, "sequence_fps"),
        ({"sequence_speed": [1.0, -2.0]}, "sequence_speed"),
        ({"poses": "random"}, "poses"),
        ({"occlusion_rate": 0.2}, "occlusion_rate"),
    ],
)
def test_bad_sequence_config_names_the_field(tmp_path, override, field):
    d = {"poses": "motion.npz", "sequence_frames": 8, **override}
    with pytest.raises(InputError, match=rf"seq\.toml: field '{field}'"):
        GenerateConfig.from_dict(d, tmp_path / "seq.toml")
    # The same values are fine without sequences (0/1 = single meshes), except the types.
    ok = GenerateConfig.from_dict({"sequence_frames": 1, "sequence_fps": [5, 30]})
    assert not ok.sequences and ok.sequence_fps == (5.0, 30.0)


def test_sequence_longer_than_the_motion_is_refused(tmp_path):
    bank = save_motion_bank(tmp_path / "walk.npz", _walk_bank(lengths=(20, 30)))
    cfg = GenerateConfig.from_dict({**TINY_SEQ, "poses": str(bank), "sequence_frames": 31,
                                    "subjects": []})  # fmt: skip
    with pytest.raises(InputError, match=r"field 'sequence_frames'.*30 frames"):
        generate(cfg, tmp_path / "out", progress=False)
    assert not list_shards(tmp_path / "out")


def test_motion_bank_subjects_and_round_trip(tmp_path):
    from rmpl.synth.generate import _prepare_motion

    bank = save_motion_bank(tmp_path / "walk.npz", _walk_bank())
    cfg = GenerateConfig.from_dict({**TINY_SEQ, "poses": str(bank)})
    out = tmp_path / "out"
    out.mkdir()
    m = load_motion_bank(_prepare_motion(cfg, out))
    assert len(m) == 1 and m.subjects[m.clip_index[0]] == "03" and m.length.tolist() == [60]
    np.testing.assert_array_equal(m.rotations, _walk_bank().rotations[40:])
    assert m.seconds_per_subject() == {"03": round(59 / 120, 2)}
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="bad.npz"):
        load_motion_bank(tmp_path / "bad.npz")
    np.savez(tmp_path / "other.npz", format=np.array("something"))
    with pytest.raises(InputError, match="field 'format'"):
        load_motion_bank(tmp_path / "other.npz")


def test_draw_window_stays_in_one_segment():
    bank = _walk_bank(lengths=(5, 200, 60))
    rng = np.random.default_rng(0)
    seen = set()
    for _ in range(200):
        seg, rows, fps, speed = draw_window(bank, 8, (10.0, 60.0), (0.8, 1.25), rng)
        seen.add(seg)
        k = np.diff(rows)
        assert len(rows) == 8 and (k == k[0]).all() and k[0] >= 1
        assert bank.start[seg] <= rows[0] and rows[-1] < bank.start[seg] + bank.length[seg]
        assert fps == pytest.approx(120.0 * speed / k[0]) and 0.8 <= speed <= 1.25
        assert 10 * 0.75 <= fps <= 60 * 1.5  # rounded to whole steps of source frames
    assert seen == {1, 2}  # the 5-frame segment is too short for 8 frames
    # A rate that divides the source rate is exact; a segment too short for the step
    # takes the longest step it holds (59 // 7 = 8 source frames: 15 frames/s).
    _, rows, fps, _ = draw_window(bank, 8, (30.0, 30.0), (1.0, 1.0), rng)
    assert fps == 30.0 and (np.diff(rows) == 4).all()
    short = _walk_bank(lengths=(60,))
    _, rows, fps, _ = draw_window(short, 8, (10.0, 10.0), (1.0, 1.0), rng)
    assert fps == 15.0 and (np.diff(rows) == 8).all()


def test_follow_root_moves_along_the_mocap_path():
    T = 5
    joints = np.repeat(_STANDING[None], T, 0) * 1.1  # a taller body, standing still
    verts = joints.copy()  # its "vertices": enough for the floor
    mocap = (
        _STANDING
        + np.stack([0.1 * np.arange(T), 0 * np.arange(T), 0.05 * np.arange(T)], -1)[:, None]
    )
    v, k = follow_root(verts, joints, mocap, np.pi / 2, np.array([1.0, 2.0]))
    hip = k[:, 11:13].mean(1)
    step = np.diff(hip, axis=0)
    # Scaled by the leg-length ratio (1.1), x turned onto +y, jump kept, lowest point on z = 0.
    np.testing.assert_allclose(step, np.tile([0.0, 0.11, 0.055], (T - 1, 1)), atol=1e-5)
    np.testing.assert_allclose(hip[:, :2].mean(0), [1.0, 2.0], atol=1e-5)
    assert v[..., 2].min() == pytest.approx(0.0, abs=1e-6) and v[0, :, 2].min() < 1e-6


@pytest.fixture(scope="module")
def tiny_seq_run(tmp_path_factory):
    _needs_synth()
    root = tmp_path_factory.mktemp("mhpseq")
    bank = save_motion_bank(root / "walk.npz", _walk_bank())
    cfg = GenerateConfig.from_dict({**TINY_SEQ, "poses": str(bank)})
    summary = generate(cfg, root / "run", progress=False)
    return root / "run", cfg, summary


def test_tiny_sequences(tiny_seq_run):
    from rmpl.data.mhp import load_mhp_sequences
    from rmpl.geometry.camera import project

    out, cfg, summary = tiny_seq_run
    assert summary["shards"] == 2 and summary["sequences"] == 2 and summary["views"] == 16
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["format"] == SEQUENCE_FORMAT and manifest["status"] == "complete"
    assert manifest["sequences"]["frames"] == 4 and manifest["config"]["sequence_frames"] == 4
    assert manifest["motion"]["seconds_per_subject"] == {"03": round(59 / 120, 2)}
    d = load_mhp_sequences(out)
    S, T, V = 2, 4, 2
    assert d["joints3d"].shape == (S, T, 17, 3) and d["keypoints"].shape == (S, T, V, 17, 2)
    assert d["scores"].shape == (S, T, V, 17) and d["times"].shape == (S, T)
    assert d["K"].shape == (S, V, 3, 3) and d["t"].shape == (S, V, 3)
    assert d["frame"].shape == (S, T) and set(d["subject"]) == {"03"}
    # Times: regular at the sequence's rate, a whole step of 120 fps source frames.
    k = np.diff(d["frame"], axis=1)
    assert (k == k[:, :1]).all() and (k >= 1).all()
    np.testing.assert_allclose(d["fps"], 120.0 / k[:, 0])
    np.testing.assert_allclose(d["times"], np.arange(T) / d["fps"][:, None])
    assert ((20 / 1.5 <= d["fps"]) & (d["fps"] <= 40 * 1.5)).all()
    # One rig per sequence: the stored cameras reproduce every frame's projections.
    uv = project(
        d["joints3d"][:, :, None].astype(float),
        d["K"][:, None, :, None],
        d["R"][:, None, :, None],
        d["t"][:, None, :, None],
    )
    np.testing.assert_allclose(uv, d["projected"], atol=1e-2)
    # One body per sequence: its bone lengths hold over the frames.
    legs = np.linalg.norm(
        d["joints3d"][:, :, [11, 12, 13, 14]] - d["joints3d"][:, :, [13, 14, 15, 16]], axis=-1
    )
    assert np.ptp(legs, axis=1).max() < 0.01, np.ptp(legs, axis=1)
    # The body walks: its mid-hip moves the same distance every frame, at a walking speed
    # (the mocap's 1 m/s scaled by the leg-length ratio), and stands on the floor.
    hip = d["joints3d"][:, :, 11:13].mean(2)
    speed = np.linalg.norm(np.diff(hip, axis=1), axis=-1) * d["fps"][:, None]
    assert np.ptp(speed, axis=1).max() < 1e-3 * speed.mean() and 0.6 < speed.mean() < 1.5
    assert 0 < d["joints3d"][..., 2].min() < 0.2
    # The detector found the person: confident keypoints land near the projections.
    ok = d["scores"] > 0.5
    err = np.linalg.norm(d["keypoints"] - uv, axis=-1)[ok]
    assert ok.sum() >= 100 and np.median(err) < MEDIAN_PX, np.median(err)


def test_sequence_resume_regenerates_only_the_killed_shard(tiny_seq_run, tmp_path):
    src, cfg, _ = tiny_seq_run
    out = tmp_path / "run"
    shutil.copytree(src, out)
    before = {p.name: p.stat().st_mtime_ns for p in list_shards(out)}
    with np.load(shard_path(out, 1)) as z:
        original = {k: z[k].copy() for k in ("joints3d", "K", "R", "t", "times", "frame")}
    shard_path(out, 1).unlink()  # killed while writing shard 1
    (out / ".shard_00001.npz.abc123.part.npz").write_bytes(b"partial")
    summary = generate(cfg, out, progress=False)
    assert summary["this_run"]["views"] == 8 and summary["shards"] == 2
    after = {p.name: p.stat().st_mtime_ns for p in list_shards(out)}
    assert after["shard_00000.npz"] == before["shard_00000.npz"]
    with np.load(shard_path(out, 1)) as z:
        for k, v in original.items():
            np.testing.assert_array_equal(z[k], v, err_msg=k)  # seeded by (seed, sequence)
    with pytest.raises(InputError, match="field 'sequence_frames'"):
        generate(dataclasses.replace(cfg, sequence_frames=5), out, progress=False)
    with pytest.raises(InputError, match="field 'sequence_frames'"):  # nor as single frames
        generate(dataclasses.replace(cfg, sequence_frames=0, poses="random"), out, progress=False)


def test_stats_refuses_a_sequence_set(tiny_seq_run, capsys):
    from rmpl.cli import main

    out, _, _ = tiny_seq_run
    assert main(["generate", "--stats", str(out)]) == 2
    assert "single-frame" in capsys.readouterr().err


def test_sequences_with_a_detector_that_follows_people(tiny_seq_run, tmp_path):
    """blazepose-multi follows people: each view is fed as a video (reset, then its frames
    in order), and the most confident person of each image is kept."""
    _, cfg, _ = tiny_seq_run
    from rmpl.data.mhp import load_mhp_sequences
    from rmpl.synth.generate import follows, make_detector

    pytest.importorskip("rmpl.synth.detect_multi")
    det = make_detector("blazepose-multi")
    assert follows(det) and not follows(make_detector("blazepose-multi-static"))
    assert not follows(make_detector("mediapipe"))
    det.close()
    run = dataclasses.replace(cfg, detector="blazepose-multi", num_meshes=1)
    generate(run, tmp_path / "run", progress=False)
    d = load_mhp_sequences(tmp_path / "run")
    assert d["keypoints"].shape == (1, 4, 2, 17, 2)
    ok = d["scores"] > 0.5
    err = np.linalg.norm(d["keypoints"] - d["projected"], axis=-1)[ok]
    assert ok.sum() >= 50 and np.median(err) < MEDIAN_PX, np.median(err)


# --------------------------------------------------------------------- multi-person scenes


@pytest.mark.parametrize(
    "override, field",
    [
        ({"people": [0, 2]}, "people"),
        ({"people": [3, 2]}, "people"),
        ({"people": [2, 9]}, "people"),
        ({"people": [2.0, 3]}, "people"),
        ({"people": [2]}, "people"),
        ({"people": [2, 3], "sequence_frames": 8, "poses": "m.npz"}, "sequence_frames"),
        ({"people": [2, 3], "occlusion_rate": 0.1}, "occlusion_rate"),
        ({"people": [2, 8], "room": 0.3}, "room"),  # 8 bodies 0.6 m apart in 0.6 x 0.6 m
    ],
)
def test_bad_scene_config_names_the_field(tmp_path, override, field):
    with pytest.raises(InputError, match=f"field '{field}'"):
        GenerateConfig.from_dict(override, tmp_path / "scene.toml")
    assert GenerateConfig.from_dict({"people": [2, 4]}).scenes
    assert not GenerateConfig.from_dict({"people": [1, 1]}).scenes


def test_match_detections_pairs_slots_with_bodies():
    from rmpl.synth.generate import match_detections

    rng = np.random.default_rng(0)
    bodies = np.stack([rng.uniform(0, 100, (17, 2)), rng.uniform(300, 400, (17, 2))])
    kp = np.full((4, 17, 2), np.nan)
    sc = np.zeros((4, 17))
    kp[0], sc[0] = bodies[1] + rng.normal(0, 3, (17, 2)), 0.9  # body 1, a few px off
    kp[1, :5], sc[1, :5] = bodies[0, :5] + 2.0, 0.8  # body 0, five joints
    kp[2], sc[2] = bodies[0] + 200.0, 0.7  # nobody's: far from both
    # slot 3 is empty
    got = match_detections(kp, sc, bodies, np.array([True, True]))
    assert got.tolist() == [1, 0, -1, -1] and got.dtype == np.int8
    # An absent body is nobody's match.
    assert match_detections(kp, sc, bodies, np.array([True, False])).tolist() == [-1, 0, -1, -1]


def test_spread_keeps_people_apart():
    from rmpl.synth.generate import spread

    where = spread(4, 1.0, np.random.default_rng(1))
    d = np.linalg.norm(where[:, None] - where[None], axis=-1)[np.triu_indices(4, 1)]
    assert where.shape == (4, 2) and np.abs(where).max() <= 1.0 and d.min() >= 0.6


def test_render_scene_bodies_hide_each_other():
    """Two boxes on one camera's axis: the nearer hides the middle of the farther, whatever
    the drawing order; one body alone renders as Renderer.render draws it."""
    pytest.importorskip("moderngl")
    from rmpl.geometry.camera import look_at
    from rmpl.synth.render import Renderer
    from tests.synth.test_render import _box

    near, faces = _box([0.0, -1.0, 1.0], [0.2, 0.2, 0.2])
    far, _ = _box([0.0, 1.0, 1.0], [0.6, 0.2, 0.6])
    try:
        r = Renderer(faces, len(near))
    except Exception as e:  # no EGL driver on this machine
        pytest.skip(f"no headless OpenGL context: {e}")
    K = np.array([[[[400.0, 0, 160], [0, 400, 120], [0, 0, 1]]]])
    R, t = look_at(np.array([0.0, -4.0, 1.0]), np.array([0.0, 0.0, 1.0]))
    R, t, size = R[None, None], t[None, None], np.array([[[320, 240]]])
    colors = np.full((1, 2, len(near), 3), 0.7, np.float32)
    try:
        for order in ([near, far], [far, near]):
            images, ids = r.render_scene(np.stack(order)[None], colors, K, R, t, size, rng=0)
            mask = ids[0]
            front, back = (0, 1) if order[0] is near else (1, 0)
            assert mask.dtype == np.int16 and mask.shape == (240, 320)
            assert mask[120, 160] == front  # the image centre: the near box
            assert mask[120, 160 + 40] == back  # beside it: the far box sticks out
            assert mask[5, 5] == -1 and set(np.unique(mask)) == {-1, 0, 1}
        # One body: the same image as render(), and its mask.
        one, ids = r.render_scene(near[None, None], colors[:, :1], K, R, t, size, rng=3)
        ref, masks = r.render(near[None], colors[:, 0], K, R, t, size, rng=3, return_masks=True)
        np.testing.assert_array_equal(one[0], ref[0])
        np.testing.assert_array_equal(ids[0] == 0, masks[0])
    finally:
        r.close()


def test_tiny_multi_person_scenes(tmp_path):
    _needs_synth()
    from rmpl.geometry.camera import project
    from rmpl.synth.generate import SCENE_FORMAT

    cfg = GenerateConfig.from_dict(
        {**TINY, "num_meshes": 2, "views": 2, "shard_size": 2, "image_size": [480, 480],
         "people": [2, 2], "detector": "blazepose-multi-static"}
    )  # fmt: skip
    summary = generate(cfg, tmp_path, progress=False)
    assert summary["scenes"] == 2 and summary["meshes"] == 4 and summary["views"] == 4
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["format"] == SCENE_FORMAT and manifest["config"]["people"] == [2, 2]
    with np.load(shard_path(tmp_path, 0)) as z:
        d = {k: z[k] for k in z.files}
    assert d["joints3d"].shape == (2, 2, 17, 3) and d["present"].all()
    assert d["keypoints"].shape == (2, 2, 4, 17, 2) and d["match"].shape == (2, 2, 4)
    assert d["projected"].shape == (2, 2, 2, 17, 2) and d["hidden"].shape == (2, 2, 2, 17)
    # Two bodies, apart on the floor, each projected by the scene's cameras.
    hips = d["joints3d"][:, :, 11:13].mean(2)
    assert (np.linalg.norm(hips[:, 0, :2] - hips[:, 1, :2], axis=-1) >= 0.6).all()
    uv = project(
        d["joints3d"][:, None].astype(float),
        d["K"][:, :, None, None],
        d["R"][:, :, None, None],
        d["t"][:, :, None, None],
    )
    np.testing.assert_allclose(uv, d["projected"], atol=1e-2)
    # The detector finds people, and each found person is matched to a body it lies on.
    found = d["scores"].max(-1) > 0  # (M, V, N)
    assert found.sum() >= 3, found.sum()
    m = d["match"]
    assert (m[found] >= 0).mean() >= 0.75 and (m[~found] == -1).all()
    s, v, n = np.nonzero(m >= 0)
    err = np.linalg.norm(d["keypoints"][s, v, n] - d["projected"][s, v, m[s, v, n]], axis=-1)
    assert np.nanmedian(err[d["scores"][s, v, n] > 0.5]) < MEDIAN_PX
    # A second run finds the set finished.
    assert generate(cfg, tmp_path, progress=False)["this_run"]["views"] == 0
