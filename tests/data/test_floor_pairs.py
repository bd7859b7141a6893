"""Training pairs on a known floor (issue 16): sequence segments levelled to their floor,
poses that keep their height (jumps stay jumps), and the floor rows given to the model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rmpl.cli.train import load_poses
from rmpl.data.sequences import SequenceBank
from rmpl.data.synthetic import PairSource, SamplerConfig, floor_rows
from rmpl.errors import InputError

EXAMPLE = Path(__file__).parents[2] / "src/rmpl/examples/walk/ground_truth.npz"


@pytest.fixture(scope="module")
def walk():
    return np.load(EXAMPLE)["points"][:, 0].astype(np.float32)


def _bank(segments: list[np.ndarray]) -> SequenceBank:
    lengths = np.array([len(s) for s in segments])
    return SequenceBank(
        np.concatenate(segments), np.cumsum(lengths) - lengths, lengths,
        np.array([f"{i:02d}" for i in range(len(segments))]), 25.0,
    )  # fmt: skip


def test_on_floor_levels_each_segment_and_drops_floating_ones(walk):
    low = walk[..., 2].min(-1)
    on_floor = walk + np.array([0, 0, 0.3], np.float32)  # recorded 0.3 m up: levelled
    jumping = walk.copy()
    jumping[:10, :, 2] += 0.5  # a jump in the first 10 frames: kept as a jump
    floating = walk.copy()
    floating[:, :, 2] += np.linspace(0, 2, len(walk), dtype=np.float32)[:, None]  # drifts up
    kept, mask = _bank([on_floor, jumping, floating]).on_floor(contact=0.07)
    assert mask.tolist() == [True, True, False]
    lowest = np.nanmin(kept.poses[..., 2], -1)
    first = lowest[: len(walk)]
    # The segment's contact level sits at the contact height above z = 0.
    assert np.percentile(first, 5) == pytest.approx(0.07, abs=1e-4)
    assert np.allclose(first - 0.07, low - np.percentile(low, 5), atol=1e-4)
    jump = lowest[len(walk) : len(walk) + 10]
    assert (jump > 0.4).all()  # still in the air


def test_pose_set_of_a_bank_keeps_subjects(walk):
    ps = _bank([walk, walk[:20]]).pose_set()
    assert len(ps) == len(walk) + 20
    assert ps.counts() == {"00": len(walk), "01": 20}


def test_load_poses_on_floor_needs_a_sequence_bank(tmp_path, walk):
    path = _bank([walk]).save(tmp_path / "seq.npz")
    poses = load_poses(str(path), on_floor=True)
    assert poses.poses.shape == walk.shape
    with pytest.raises(InputError, match="sequence bank"):
        load_poses(str(tmp_path / "missing.npz"), on_floor=True)


def test_floor_rate_needs_poses_on_a_floor():
    with pytest.raises(ValueError, match="keep_height"):
        SamplerConfig(floor_rate=0.5)
    with pytest.raises(ValueError, match="floor_rate"):
        SamplerConfig(keep_height=True, floor_rate=1.5)
    with pytest.raises(ValueError, match=">= 0"):
        SamplerConfig(keep_height=True, floor_noise_m=-1.0)


def test_floor_rows():
    rng = np.random.default_rng(0)
    assert floor_rows(8, 0.0, 0.02, 1.0, rng) is None
    rows = floor_rows(2000, 0.75, 0.02, 1.0, rng)
    known = np.isfinite(rows).all(-1)
    assert 0.7 < known.mean() < 0.8
    assert np.isnan(rows[~known]).all()
    assert np.allclose(np.linalg.norm(rows[known, :3], axis=-1), 1.0, atol=1e-5)
    assert 0.015 < rows[known, 3].std() < 0.025
    exact = floor_rows(5, 1.0, 0.0, 0.0, rng)
    assert np.allclose(exact, [[0, 0, 1, 0]] * 5)


def test_pairs_keep_their_height_and_carry_the_floor(walk):
    high = walk + np.array([0, 0, 0.6], np.float32)  # every pose 0.6 m up (a jump, a stage)
    cfg = SamplerConfig(keep_height=True, floor_rate=1.0, scale_range=(1.0, 1.0), mirror=0.0)
    b = PairSource(high, cfg, seed=0).batch(16, 2, train=False)
    assert b.floor.shape == (16, 4)
    assert np.allclose(b.floor, [[0, 0, 1, 0]] * 16)  # validation batches: the exact floor
    lowest = np.nanmin(b.target[..., 2], -1)
    assert (lowest > 0.55).all()
    flat = PairSource(high, SamplerConfig(scale_range=(1.0, 1.0)), seed=0).batch(16, 2)
    assert flat.floor is None
    assert np.allclose(np.nanmin(flat.target[..., 2], -1), 0.0, atol=1e-5)
