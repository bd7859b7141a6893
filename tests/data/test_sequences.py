"""Synthetic training windows: motion in time, one rig per window, temporal detector noise."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rmpl.data.sequences import SequenceBank, SequenceSource, TemporalNoise
from rmpl.errors import InputError


def _bank(segments=3, frames=240, fps=60.0, seed=0) -> SequenceBank:
    """Walking-like motion: a fixed pose translated along x, arms swinging."""
    rng = np.random.default_rng(seed)
    pose = np.array(
        [[0, 0, 1.6], [0.03, 0.05, 1.65], [-0.03, 0.05, 1.65], [0.08, 0, 1.62], [-0.08, 0, 1.62],
         [0.18, 0, 1.4], [-0.18, 0, 1.4], [0.22, 0, 1.1], [-0.22, 0, 1.1], [0.24, 0, 0.85],
         [-0.24, 0, 0.85], [0.1, 0, 0.95], [-0.1, 0, 0.95], [0.1, 0, 0.5], [-0.1, 0, 0.5],
         [0.1, 0, 0.08], [-0.1, 0, 0.08]], float)  # fmt: skip
    parts, starts = [], []
    for s in range(segments):
        t = np.arange(frames) / fps
        p = np.repeat(pose[None], frames, 0).copy()
        p[..., 0] += 1.2 * t[:, None] * (s + 1) / segments
        p[:, 9, 1] += 0.2 * np.sin(2 * np.pi * t)
        p += 0.002 * rng.standard_normal(p.shape)
        starts.append(s * frames)
        parts.append(p)
    subjects = np.array(["01", "02", "03"][:segments])
    return SequenceBank(
        np.concatenate(parts).astype(np.float32),
        np.array(starts),
        np.full(segments, frames),
        subjects,
        fps,
    )


def test_batch_shapes_masks_and_times():
    src = SequenceSource(_bank(), seed=0)
    b = src.batch(6, 20, 3)
    assert b.rays.shape == (6, 20, 3, 17, 6) and b.scores.shape == (6, 20, 3, 17)
    assert b.target.shape == (6, 20, 17, 3) and b.times.shape == (6, 20)
    missing = b.scores == 0
    assert np.isnan(b.keypoints[missing]).all()
    assert np.isfinite(b.keypoints[~missing]).all()
    assert (b.rays[missing] == 0).all() and np.isfinite(b.rays).all()
    dt = np.diff(b.times, axis=1)
    assert (dt > 0).all()
    fps = 1 / dt[:, 0]
    assert (fps > 10 * 0.99).all() and (fps < 120 * 1.01).all()
    assert np.allclose(dt, dt[:, :1], rtol=1e-3)  # one rate per window


def test_seeded_sources_repeat_and_differ_by_seed():
    a = SequenceSource(_bank(), seed=3).batch(4, 10, 2)
    b = SequenceSource(_bank(), seed=3).batch(4, 10, 2)
    c = SequenceSource(_bank(), seed=4).batch(4, 10, 2)
    assert np.array_equal(a.rays, b.rays) and not np.array_equal(a.target, c.target)


def test_one_placement_per_window_keeps_the_motion_rigid_over_time():
    """Placement (scale, turn, shift) is per window: bone lengths stay constant in time."""
    b = SequenceSource(_bank(), seed=1).batch(5, 30, 2)
    bone = np.linalg.norm(b.target[:, :, 15] - b.target[:, :, 13], axis=-1)  # shin (B, T)
    assert np.allclose(bone, bone[:, :1], atol=0.02)


def test_occlusion_bursts_are_runs_in_time():
    quiet = TemporalNoise(burst_rate=0.0, gap_rate=0.0, drop_rate=0.0, identity_rate=0.0)
    noisy = replace(quiet, burst_rate=4.0, burst_seconds=(0.5, 0.6))
    a = SequenceSource(_bank(), temporal=quiet, seed=0).batch(8, 40, 3)
    b = SequenceSource(_bank(), temporal=noisy, seed=0).batch(8, 40, 3)
    miss_a, miss_b = (a.scores == 0).mean(), (b.scores == 0).mean()
    assert miss_b > miss_a + 0.05
    # Runs: a missing keypoint is mostly missing in the next frame too.
    m = b.scores == 0
    both = (m[:, 1:] & m[:, :-1]).sum() / max(m[:, :-1].sum(), 1)
    assert both > 0.7


def test_whole_frame_gaps():
    tn = TemporalNoise(gap_rate=1.0, gap_frames=5, burst_rate=0, drop_rate=0, identity_rate=0)
    b = SequenceSource(_bank(), temporal=tn, seed=0).batch(8, 30, 2)
    empty = ~(b.scores > 0).any((2, 3))  # (B, T)
    assert empty.any(1).mean() > 0.5


def test_bank_split_save_load(tmp_path):
    bank = _bank()
    train, val = bank.split(["03"])
    assert len(train) == 2 and len(val) == 1 and set(val.subject) == {"03"}
    assert np.array_equal(val.poses, bank.poses[480:720])
    path = bank.save(tmp_path / "seq.npz")
    back = SequenceBank.load(path)
    assert np.array_equal(back.poses, bank.poses) and back.fps == bank.fps
    assert list(back.subject) == list(bank.subject)


def test_bad_bank_files(tmp_path):
    other = tmp_path / "other.npz"
    np.savez(other, poses=np.zeros((3, 17, 3)))
    with pytest.raises(InputError, match="kind"):
        SequenceBank.load(other)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(InputError, match="junk.npz"):
        SequenceBank.load(junk)


def test_noise_keys_are_checked():
    with pytest.raises(ValueError, match="unknown"):
        TemporalNoise.from_dict({"burst_rat": 1})
    assert TemporalNoise.from_dict({"fps_range": [20, 30]}).fps_range == (20, 30)
