"""The motion library of ``rmpl simulate`` (rmpl.simulate.motion): the shipped file, the
draws of pick_segment, the rebuild from the CMU folder (needs ../shared/data), and one
segment on an anny body (needs anny; its cache is built on first use, see
tests.conftest.synth_ready)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rmpl.data.sequences import MAX_JOINT_SPEED
from rmpl.errors import InputError
from rmpl.simulate.motion import (
    JOINT_STEP,
    KINDS,
    LIBRARY,
    RATE,
    build_motion_library,
    load_motion_library,
    pick_segment,
)
from tests.conftest import synth_ready


def test_shipped_library_loads():
    bank, kinds = load_motion_library()
    N, K = bank.rotations.shape[:2]
    assert bank.rotations.dtype == np.float32 and bank.rotations.shape == (N, K, 3, 3)
    assert bank.joints.dtype == np.float32 and bank.joints.shape == (N, 17, 3)
    assert kinds.shape == (len(bank),) and set(kinds) == set(KINDS)
    assert np.all(bank.fps == RATE)
    assert bank.start[-1] + bank.length[-1] == N
    det = np.linalg.det(bank.rotations[::97].astype(float))
    assert np.allclose(det, 1.0, atol=1e-4)
    assert load_motion_library() is load_motion_library(LIBRARY)  # cached
    assert LIBRARY.stat().st_size < 2.2e6


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_has_five_seconds(kind):
    bank, kinds = load_motion_library()
    seconds = (bank.length[kinds == kind] - 1) / RATE
    assert seconds.sum() >= 5.0, (kind, seconds)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seconds", [0.0, 0.7, 4.0, 45.0])
def test_pick_segment_rows_are_continuous(kind, seconds):
    bank, kinds = load_motion_library()
    seg, rows = pick_segment(bank, kinds, kind, seconds, np.random.default_rng(7))
    assert kinds[seg] == kind
    assert len(rows) == round(seconds * RATE) + 1
    a, n = bank.start[seg], bank.length[seg]
    assert np.all((rows >= a) & (rows < a + n))
    assert np.all(np.abs(np.diff(rows)) == 1)  # forward, or backward at an end of the segment
    speed = np.linalg.norm(np.diff(bank.joints[rows], axis=0), axis=-1) * RATE  # (T - 1, 17)
    assert speed.max(initial=0.0) < MAX_JOINT_SPEED


def test_pick_segment_ping_pongs_a_short_segment():
    bank, kinds = load_motion_library()
    seg, rows = pick_segment(bank, kinds, "run", 10.0, np.random.default_rng(0))
    runs = np.flatnonzero(kinds == "run")
    assert bank.length[seg] == bank.length[runs].max() < len(rows)
    turns = np.flatnonzero(np.diff(np.sign(np.diff(rows))))  # where the direction changes
    ends = rows[turns + 1]
    assert np.all((ends == bank.start[seg]) | (ends == bank.start[seg] + bank.length[seg] - 1))


def test_pick_segment_rejects_an_unknown_kind():
    bank, kinds = load_motion_library()
    with pytest.raises(ValueError, match="kind"):
        pick_segment(bank, kinds, "swim", 1.0, np.random.default_rng(0))


def test_missing_or_wrong_file_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_motion_library(tmp_path / "missing.npz")
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, format=np.array("something else"))
    with pytest.raises(InputError, match="format"):
        load_motion_library(wrong)
    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(InputError):
        load_motion_library(tmp_path / "text.npz")


@pytest.mark.shared
def test_rebuilt_library_equals_the_shipped_one(shared_data, tmp_path):
    cmu = shared_data / "cmu_mocap"
    if not cmu.is_dir():
        pytest.skip(f"CMU motion capture not found at {cmu}")
    rebuilt, kinds = load_motion_library(build_motion_library(cmu, tmp_path / "motion.npz"))
    shipped, shipped_kinds = load_motion_library()
    for key in ("start", "length", "first", "clip_index", "clips", "subjects", "fps"):
        assert np.array_equal(getattr(rebuilt, key), getattr(shipped, key)), key
    assert np.array_equal(kinds, shipped_kinds)
    # Within one quantisation step (float16's rounding is coarser: 1e-3 near 1).
    assert np.allclose(rebuilt.rest_dirs, shipped.rest_dirs, atol=1e-6)
    assert np.allclose(rebuilt.rotations, shipped.rotations, atol=1e-3)
    assert np.allclose(rebuilt.joints, shipped.joints, atol=2 * JOINT_STEP)


def test_a_walk_on_anny_moves_its_feet_along_the_floor():
    cache = synth_ready("anny")
    from rmpl.synth.body import BodyModel, sample_phenotypes
    from rmpl.synth.generate.sequences import _sequence_pose, follow_root

    bank, kinds = load_motion_library()
    body = BodyModel(joints="halpe26", cache_dir=cache)
    rng = np.random.default_rng(3)
    seg, rows = pick_segment(bank, kinds, "walk", 2.0, rng)
    phen = sample_phenotypes(1, rng)[0]
    worker = SimpleNamespace(body=body, motion=bank, cfg=SimpleNamespace(perturb_deg=0.0))
    pose = _sequence_pose(worker, seg, rows, phen, False, rng)
    bodies = body(pose, np.repeat(phen[None], len(rows), axis=0))
    mocap = bank.joints[rows].astype(float)
    _, joints = follow_root(bodies.vertices, bodies.keypoints, mocap, 0.0, np.zeros(2))
    seconds = (len(rows) - 1) / RATE
    hips = np.linalg.norm(joints[-1, 19, :2] - joints[0, 19, :2])  # mid-hip, metres
    assert 0.5 < hips / seconds < 2.5
    feet = joints[:, [15, 16, 20, 21, 22, 23, 24, 25]]  # ankles, toes, heels: (T, 8, 3)
    assert np.all(feet[..., 2].min(axis=1) < 0.15)  # a foot on the floor in every frame
    assert feet[..., 2].min() > -0.02
    moved = np.linalg.norm(feet[-1, :, :2] - feet[0, :, :2], axis=-1).mean()
    assert abs(moved - hips) < 0.25 * hips  # the feet go where the body goes
