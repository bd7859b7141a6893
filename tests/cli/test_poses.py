"""rmpl poses: a pose bank from motion-capture files (one real CMU clip)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.synth.motion import load_pose_set


@pytest.mark.shared
def test_pose_bank_from_one_cmu_clip(shared_data, tmp_path):
    subject = shared_data / "cmu_mocap/asfamc/data/CMU/asfamc/subjects/03"
    if not subject.is_dir():
        pytest.skip(f"{subject} not found")
    motion = tmp_path / "motion" / "03"
    motion.mkdir(parents=True)
    clip = min(subject.glob("*.amc"), key=lambda p: p.stat().st_size)
    for f in (subject / "03.asf", clip):
        shutil.copy(f, motion)
    out = tmp_path / "bank.npz"
    assert main(["poses", str(motion.parent), "--out", str(out), "--fps", "5"]) == 0
    bank = load_pose_set(out)
    assert set(bank.counts()) == {"03"}
    assert bank.poses.shape[1:] == (17, 3) and np.isfinite(bank.poses).all()
    # Metres, z up, standing on the floor: ankles near z = 0, the nose 1.2-2.0 m above them.
    height = bank.poses[:, 0, 2] - bank.poses[:, 15:17, 2].min(1)
    assert 1.2 < np.median(height) < 2.0
    # More frames kept at a higher rate.
    main(["poses", str(motion.parent), "--out", str(tmp_path / "b10.npz"), "--fps", "10"])
    assert len(load_pose_set(tmp_path / "b10.npz")) > len(bank)


def test_bad_arguments_are_clear(tmp_path, capsys):
    assert main(["poses", str(tmp_path / "nowhere"), "--out", str(tmp_path / "b.npz")]) == 2
    assert "folder of motion-capture files" in capsys.readouterr().err
    assert main(["poses", str(tmp_path), "--out", str(tmp_path / "b.txt")]) == 2
    assert not (tmp_path / "b.txt").exists()


@pytest.mark.shared
def test_sequence_bank_from_one_cmu_clip(shared_data, tmp_path):
    from rmpl.data.sequences import SequenceBank

    subject = shared_data / "cmu_mocap/asfamc/data/CMU/asfamc/subjects/03"
    if not subject.is_dir():
        pytest.skip(f"{subject} not found")
    motion = tmp_path / "motion" / "03"
    motion.mkdir(parents=True)
    clip = min(subject.glob("*.amc"), key=lambda p: p.stat().st_size)
    for f in (subject / "03.asf", clip):
        shutil.copy(f, motion)
    out = tmp_path / "seq.npz"
    assert main(["poses", str(motion.parent), "--sequences", "--out", str(out)]) == 0
    bank = SequenceBank.load(out)
    assert bank.fps == 60 and set(bank.subject) == {"03"} and len(bank) >= 1
    # Continuous motion: at 60 frames/s no joint jumps more than 10 cm between frames.
    first = bank.poses[bank.start[0] : bank.start[0] + bank.length[0]]
    assert np.abs(np.diff(first, axis=0)).max() < 0.1
    assert main(["poses", str(motion.parent), "--sequences", "--fps", "0", "--out",
                 str(out)]) == 2  # fmt: skip
