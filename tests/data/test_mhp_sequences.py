"""load_mhp_sequences / SequenceShardSource on a small MHP sequence directory written in the
shard format (no anny, renderer or detector: the 'detections' are exact projections)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.data.mhp import SequenceShardSource, load_mhp, load_mhp_sequences
from rmpl.data.sequences import SequenceBank, SequenceBatch, SequenceSource
from rmpl.errors import InputError
from rmpl.geometry.camera import project
from rmpl.synth.cameras import sample_cameras
from rmpl.synth.generate import SEQUENCE_ARRAYS, GenerateConfig, _write_manifest, shard_path
from tests.data.test_mhp import _fake_mhp

S, T, V = 3, 10, 4


def _fake_sequences(root, shards=2, seed=0, frames=T, views=V):
    """Sequences of a point cloud person walking along +x at 1 m/s, 25 frames/s."""
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    cfg = GenerateConfig(
        poses="motion.npz", num_meshes=S * shards, views=views, shard_size=S,
        sequence_frames=frames,
    )  # fmt: skip
    _write_manifest(root, cfg, "exact", {})
    for s in range(shards):
        fps = np.full(S, 25.0)
        times = np.arange(frames) / fps[:, None]  # (S, T)
        body = rng.normal([0, 0, 1.0], 0.3, (S, 1, 17, 3))
        joints = body + np.stack([times, 0 * times, 0 * times], -1)[:, :, None]
        K, R, t, size = sample_cameras(views, joints[:, :, 11:13].mean((1, 2)), "universal", rng)
        kp = project(joints[:, :, None], K[:, None, :, None], R[:, None, :, None],
                     t[:, None, :, None])  # fmt: skip
        scores = rng.uniform(0.5, 1.0, (S, frames, views, 17))
        scores[:, 1, 0, 0] = 0.0  # a miss, with a stale coordinate: must become NaN
        arrays = {
            "joints3d": joints.astype(np.float32),
            "keypoints": kp.astype(np.float32),
            "scores": scores.astype(np.float32),
            "projected": kp.astype(np.float32),
            "times": times,
            "fps": fps,
            "speed": np.ones(S),
            "K": K,
            "R": R,
            "t": t,
            "size": size.astype(np.int32),
            "phenotypes": np.zeros((S, 6), np.float32),
            "subject": np.array(["03" if s == 1 else "01"] * S),
            "clip": np.array(["c"] * S),
            "frame": np.arange(frames)[None].repeat(S, 0) * 4,
            "mirrored": np.zeros(S, bool),
        }
        assert set(arrays) == set(SEQUENCE_ARRAYS)
        np.savez_compressed(shard_path(root, s), **arrays, stats=np.array(json.dumps({})))
    return root


def test_load_sequences_and_split(tmp_path):
    _fake_sequences(tmp_path)
    d = load_mhp_sequences(tmp_path)
    assert d["joints3d"].shape == (2 * S, T, 17, 3) and d["keypoints"].shape == (2 * S, T, V, 17, 2)
    assert d["scores"].shape == (2 * S, T, V, 17) and d["times"].shape == (2 * S, T)
    assert d["K"].shape == (2 * S, V, 3, 3) and d["frame"].shape == (2 * S, T)
    assert np.isnan(d["keypoints"][:, 1, 0, 0]).all() and np.isfinite(d["keypoints"][:, 0]).all()
    assert set(load_mhp_sequences(tmp_path, subjects=["03"])["subject"]) == {"03"}
    assert len(load_mhp_sequences(tmp_path, exclude_subjects=["03"])["joints3d"]) == S
    with pytest.raises(InputError, match="subject"):
        load_mhp_sequences(tmp_path, subjects=["99"])


def test_single_frame_and_sequence_sets_are_not_confused(tmp_path):
    _fake_sequences(tmp_path / "seq")
    _fake_mhp(tmp_path / "single")
    with pytest.raises(InputError, match="field 'format'.*load_mhp_sequences"):
        load_mhp(tmp_path / "seq")
    with pytest.raises(InputError, match="field 'format'.*load_mhp\\)"):
        load_mhp_sequences(tmp_path / "single")
    with pytest.raises(InputError, match="manifest.json"):
        load_mhp_sequences(tmp_path / "nowhere")


def _ray_distance(b: SequenceBatch) -> np.ndarray:
    """Distance of each valid ray to its target joint, metres."""
    o, d = b.rays[..., :3].astype(float), b.rays[..., 3:].astype(float)
    x = b.target[:, :, None].astype(float) - o
    perp = x - (x * d).sum(-1, keepdims=True) * d
    return np.linalg.norm(perp, axis=-1)[b.scores > 0]


@pytest.mark.parametrize("augment", [False, True])
def test_sequence_source_matches_sequence_batch(tmp_path, augment):
    _fake_sequences(tmp_path)
    src = SequenceShardSource(tmp_path, augment=augment, seed=0)
    assert (src.num_sequences, src.num_frames, src.num_views) == (2 * S, T, V)
    b = src.batch(8, 6, 3)
    # The same fields, shapes and dtypes as the parametric SequenceSource's batches.
    bank = SequenceBank(
        np.zeros((100, 17, 3), np.float32) + [0, 0, 1.0], np.array([0]), np.array([100]),
        np.array(["01"]), 60.0,
    )  # fmt: skip
    ref = SequenceSource(bank, seed=0).batch(8, 6, 3)
    for name in SequenceBatch.__dataclass_fields__:
        mine, theirs = getattr(b, name), getattr(ref, name)
        if name == "floor":  # neither carries a floor here (MHP sequences never do)
            assert mine is None and theirs is None
            continue
        assert mine.shape == theirs.shape and mine.dtype == theirs.dtype, name
    # Exact keypoints: every ray passes through its joint, also after the augmentation.
    assert _ray_distance(b).max() < 1e-4
    assert np.all(b.rays[b.scores == 0] == 0) and np.isnan(b.keypoints[b.scores == 0]).all()
    # Windows are consecutive frames: the clock ticks at 25 frames/s, the walker moves 4 cm.
    np.testing.assert_allclose(np.diff(b.times, axis=1), 0.04, atol=1e-5)
    step = np.diff(b.target.mean(2), axis=1)  # (B, T - 1, 3)
    assert np.allclose(np.linalg.norm(step, axis=-1), 0.04, atol=1e-4)
    if not augment:
        assert (b.times[:, 0] == 0).all()
        np.testing.assert_allclose(step, np.tile([0.04, 0, 0], (8, 5, 1)), atol=1e-4)
    # Views of one window are distinct cameras, the same for all its frames.
    C = -np.einsum("bvji,bvj->bvi", b.R, b.t)
    assert np.linalg.norm(C[:, 0] - C[:, 1], axis=-1).min() > 1e-6


def test_sequence_source_drop_and_errors(tmp_path):
    _fake_sequences(tmp_path)
    src = SequenceShardSource(tmp_path, drop_rate=0.5, seed=1)
    assert 0.35 < (src.batch(16, T, V).scores == 0).mean() < 0.65
    assert (src.batch(16, T, V, train=False).scores == 0).mean() < 0.1
    with pytest.raises(ValueError, match="frames"):
        src.batch(2, T + 1, 2)
    with pytest.raises(ValueError, match="num_views"):
        src.batch(2, 4, V + 1)
    other = _fake_sequences(tmp_path / "short", frames=6, seed=2)
    with pytest.raises(InputError, match="short.*sequence_frames, views"):
        SequenceShardSource([tmp_path, other])
    two = SequenceShardSource([tmp_path, _fake_sequences(tmp_path / "b", seed=3)], seed=0)
    assert two.num_sequences == 4 * S and two.batch(4, 5, 2).rays.shape == (4, 5, 2, 17, 6)
