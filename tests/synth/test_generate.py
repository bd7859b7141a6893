"""rmpl generate: config validation (always), and a tiny end-to-end generation with anny,
the EGL renderer and MediaPipe (skipped when they or anny's cache are absent): projection
accuracy, resume after an interrupted run, --stats, Ray."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.synth.generate import GenerateConfig, generate, list_shards, occlude, shard_path
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
    try:
        summary = generate(cfg, tmp_path, workers=2, ray_address="local", progress=False)
    finally:
        ray.shutdown()
    assert summary["shards"] == 2 and summary["views"] == 4
    assert [p.name for p in list_shards(tmp_path)] == ["shard_00000.npz", "shard_00001.npz"]
