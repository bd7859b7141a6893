"""rmpl run --duplicate-tolerance: off, a number, or one clear error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.io.poses import load_poses

EXAMPLE = Path(__file__).resolve().parents[2] / "src/rmpl/examples/walk"
BASE = ["run", "--calib", str(EXAMPLE / "calibration.toml"), "--keypoints",
        str(EXAMPLE / "keypoints.json"), "--no-pictures", "--pose2sim", "off",
        "--formats", "npz", "--model", "default"]  # fmt: skip


def test_off_and_a_tolerance_run_and_one_person_is_kept(tmp_path):
    assert main([*BASE, "--out", str(tmp_path / "off"), "--duplicate-tolerance", "off"]) == 0
    assert main([*BASE, "--out", str(tmp_path / "t"), "--duplicate-tolerance", "0.3"]) == 0
    off, tol = (load_poses(tmp_path / x / "poses.npz") for x in ("off", "t"))
    assert off.points.shape[1] == tol.points.shape[1] == 1  # one walker: nothing to drop
    np.testing.assert_array_equal(off.points, tol.points)


@pytest.mark.parametrize("value", ["0", "-0.2", "none", "inf"])
def test_a_bad_tolerance_is_refused_at_parse_time(tmp_path, value, capsys):
    with pytest.raises(SystemExit) as e:
        main([*BASE, "--out", str(tmp_path / "x"), "--duplicate-tolerance", value])
    assert e.value.code == 2 and "--duplicate-tolerance" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(("value", "expected"), [("off", None), ("0.35", 0.35), (None, 0.2)])
def test_the_tolerance_reaches_the_association(tmp_path, monkeypatch, value, expected):
    import rmpl.pipeline.runner as runner

    seen = []
    real = runner.run_with_floor

    def spy(*args, **kwargs):
        seen.append(args[5].association.duplicate_tolerance)
        return real(*args, **kwargs)

    monkeypatch.setattr(runner, "run_with_floor", spy)
    extra = [] if value is None else ["--duplicate-tolerance", value]
    assert main([*BASE, "--out", str(tmp_path / "o"), *extra]) == 0
    assert seen == [expected]
