"""ShardSource / load_mhp on a small MHP directory written in the shard format (no anny,
renderer or detector needed: the 'detections' are exact projections)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.data.mhp import MixSource, ShardSource, load_mhp
from rmpl.errors import InputError
from rmpl.geometry.camera import project
from rmpl.synth.cameras import sample_cameras
from rmpl.synth.generate import GenerateConfig, _write_manifest, shard_path


def _fake_mhp(root, meshes=6, views=5, shards=2, seed=0):
    rng = np.random.default_rng(seed)
    cfg = GenerateConfig(num_meshes=meshes * shards, views=views, shard_size=meshes)
    _write_manifest(root, cfg, "exact", {})
    for s in range(shards):
        joints = rng.normal([0, 0, 1.0], 0.3, (meshes, 17, 3))
        K, R, t, size = sample_cameras(views, joints[:, 11:13].mean(1), "universal", rng)
        kp = project(joints[:, None], K[:, :, None], R[:, :, None], t[:, :, None])
        scores = rng.uniform(0.5, 1.0, (meshes, views, 17))
        scores[:, 0, 0] = 0.0  # a miss, with a stale coordinate: must become NaN
        np.savez_compressed(
            shard_path(root, s),
            joints3d=joints.astype(np.float32),
            keypoints=kp.astype(np.float32),
            scores=scores.astype(np.float32),
            projected=kp.astype(np.float32),
            K=K,
            R=R,
            t=t,
            size=size.astype(np.int32),
            occluded=np.zeros((meshes, views, 17), bool),
            phenotypes=np.zeros((meshes, 6), np.float32),
            subject=np.array(["03" if s == 1 else "01"] * meshes),
            clip=np.array(["c"] * meshes),
            frame=np.arange(meshes),
            mirrored=np.zeros(meshes, bool),
            stats=np.array(json.dumps({})),
        )
    return root


def _ray_distance(batch):
    """Distance of each valid ray to its target joint, metres."""
    o, d = batch.rays[..., :3].astype(float), batch.rays[..., 3:].astype(float)
    x = batch.target[:, None].astype(float) - o
    perp = x - (x * d).sum(-1, keepdims=True) * d
    return np.linalg.norm(perp, axis=-1)[batch.scores > 0]


def test_load_mhp_and_split(tmp_path):
    _fake_mhp(tmp_path)
    d = load_mhp(tmp_path)
    assert d["joints3d"].shape == (12, 17, 3) and d["keypoints"].shape == (12, 5, 17, 2)
    assert np.isnan(d["keypoints"][:, 0, 0]).all()
    assert len(load_mhp(tmp_path, exclude_subjects=["03"])["joints3d"]) == 6
    assert set(load_mhp(tmp_path, subjects=["03"])["subject"]) == {"03"}
    with pytest.raises(InputError, match="subject"):
        load_mhp(tmp_path, subjects=["99"])
    with pytest.raises(InputError, match="manifest.json"):
        load_mhp(tmp_path / "nope")


@pytest.mark.parametrize("augment", [False, True])
def test_shard_source_batch(tmp_path, augment):
    _fake_mhp(tmp_path)
    src = ShardSource(tmp_path, drop_rate=0.0, augment=augment, seed=0)
    b = src.batch(32, 3)
    assert b.rays.shape == (32, 3, 17, 6) and b.rays.dtype == np.float32
    assert b.scores.shape == (32, 3, 17) and b.target.shape == (32, 17, 3)
    assert b.keypoints.shape == (32, 3, 17, 2)
    assert b.K.shape == (32, 3, 3, 3) and b.R.shape == (32, 3, 3, 3) and b.t.shape == (32, 3, 3)
    # Exact keypoints: every ray passes through its 3D joint, also after the augmentation.
    assert _ray_distance(b).max() < 1e-4
    assert np.all(b.rays[b.scores == 0] == 0) and np.isnan(b.keypoints[b.scores == 0]).all()
    # Views of one sample are distinct cameras.
    C = -np.einsum("bvji,bvj->bvi", b.R, b.t)
    assert np.linalg.norm(C[:, 0] - C[:, 1], axis=-1).min() > 1e-6
    assert isinstance(src.rng, np.random.Generator)


def test_shard_source_drop_and_errors(tmp_path):
    _fake_mhp(tmp_path)
    src = ShardSource(tmp_path, exclude_subjects=["03"], drop_rate=0.5, seed=1)
    assert src.num_meshes == 6
    b = src.batch(64, 4)
    assert 0.35 < (b.scores == 0).mean() < 0.65
    assert (src.batch(64, 4, train=False).scores == 0).mean() < 0.1
    with pytest.raises(ValueError, match="num_views"):
        src.batch(4, 6)
    mix = MixSource([src, ShardSource(tmp_path, seed=2)], [1.0, 1.0], seed=3)
    assert mix.batch(8, 2).rays.shape == (8, 2, 17, 6)
    assert all(s.rng is mix.rng for s in mix.sources)


def test_shard_source_mixed_view_counts(tmp_path):
    """Directories with 5 and 3 views per mesh: a batch never picks a padded (absent) view,
    and asks for more views than the smaller directory has only from the larger one."""
    a, b = _fake_mhp(tmp_path / "a", views=5), _fake_mhp(tmp_path / "b", views=3, seed=1)
    src = ShardSource([a, b], drop_rate=0.0, augment=False, seed=0)
    assert src.num_meshes == 24 and src.num_views == 5
    for V in (3, 4, 5):
        for _ in range(3):
            batch = src.batch(64, V)
            # Every picked view is a real camera with its exact keypoints (padding has
            # identity R, zero t and no scores).
            assert np.isfinite(batch.rays).all()
            assert (batch.scores > 0).mean() > 0.9
            assert _ray_distance(batch).max() < 1e-4
            assert not np.any(np.all(batch.t == 0, axis=-1))
    # 3 views draw from both directories, 4 only from the 5-view one.
    three = {tuple(x) for x in src.batch(256, 3).target[:, 0].round(5)}
    four = {tuple(x) for x in src.batch(256, 4).target[:, 0].round(5)}
    small = {tuple(x) for x in src.data["joints3d"][12:, 0].round(5)}
    assert three & small and not four & small
    with pytest.raises(ValueError, match="num_views"):
        src.batch(4, 6)
