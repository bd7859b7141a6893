"""The Python API's bad-input corpus: every case is one clear InputError (issue 13, item 7),
and absurd pixel coordinates are treated as missing (item 11)."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.inference import Lifter
from rmpl.pipeline.runner import RunConfig, run
from tests.reliability._scene import make_rig


@pytest.fixture(scope="module")
def lifter():
    return Lifter.from_pretrained("default", backend="torch")


@pytest.fixture(scope="module")
def scene():
    rig = make_rig(3)
    X = np.random.default_rng(0).uniform(-0.4, 0.4, (4, 17, 3)) + [0, 0, 1]
    return rig, X, rig.project(X), np.full((4, 3, 17), 0.9)


CASES = {
    "rig as a path": (dict(rig="calib.toml"), "field 'rig': expected an rmpl.Rig"),
    "rig as a list": (dict(rig=[1, 2, 3]), "field 'rig': expected an rmpl.Rig"),
    "ragged keypoints": (dict(keypoints="ragged"), "field 'keypoints'.*not ragged"),
    "boolean keypoints": (dict(keypoints="bool"), "field 'keypoints'.*real numbers"),
    "complex scores": (dict(scores="complex"), "field 'scores'.*real numbers"),
    "batch_size 0": (dict(batch_size=0), "field 'batch_size': expected an integer >= 1"),
    "batch_size 2.5": (dict(batch_size=2.5), "field 'batch_size'"),
    "up all zeros": (dict(up=np.zeros(3)), "field 'up': expected a finite, non-zero"),
    "up with NaN": (dict(up=[0.0, np.nan, 1.0]), "field 'up'"),
    "up of 2 numbers": (dict(up=[0.0, 1.0]), "field 'up'"),
    "people axis": (dict(keypoints="people"), "people axis"),
    "too few views": (dict(keypoints="2views"), "3 views to match"),
    "scores of another shape": (dict(scores="short"), "field 'scores': expected shape"),
    "no keypoint at all": (dict(scores="zero"), "at least one keypoint"),
}


def _arguments(change: dict, scene) -> dict:
    rig, _, kp, sc = scene
    args = dict(keypoints=kp, scores=sc, rig=rig)
    for key, value in change.items():
        if not isinstance(value, str) or key == "rig":
            pass
        elif value == "ragged":
            value = [kp[0].tolist(), kp[1, :2].tolist()]
        elif value == "bool":
            value = kp > 100
        elif value == "complex":
            value = sc + 0j
        elif value == "people":
            args["scores"] = sc[:, :, None]
            value = kp[:, :, None]
        elif value == "2views":
            args["scores"] = sc[:, :2]
            value = kp[:, :2]
        elif value == "short":
            value = sc[:, :, :5]
        elif value == "zero":
            value = np.zeros_like(sc)
        args[key] = value
    return args


@pytest.mark.parametrize("case", sorted(CASES))
def test_lift_bad_input_is_one_clear_error(lifter, scene, case):
    change, message = CASES[case]
    with pytest.raises(InputError, match=message):
        lifter.lift(**_arguments(change, scene))


def test_absurd_pixels_are_missing_in_the_lifter(lifter, scene, caplog):
    rig, X, kp, sc = scene
    bad = kp.copy()
    bad[:, 0] = 1e13  # view 0 sends absurd coordinates for every joint
    with caplog.at_level(logging.WARNING):
        got = lifter.lift(bad, sc, rig)
    missing, zero = kp.copy(), sc.copy()
    missing[:, 0], zero[:, 0] = np.nan, 0.0
    want = lifter.lift(missing, zero, rig)  # view 0 missing
    assert "68 keypoints lie more than 1 image size beyond their image" in caplog.text
    assert (got.num_views == 2).all()  # view 0 counted as not seeing anything
    np.testing.assert_array_equal(got.points, want.points)


@pytest.mark.parametrize("method", ["triangulate", "robust"])
def test_absurd_pixels_are_missing_in_triangulation(scene, caplog, method):
    rig, X, kp, sc = scene
    bad = kp.copy()
    bad[:, 0, 3:5] = [1e14, -1e15]
    with caplog.at_level(logging.WARNING):
        poses = run(bad[:, :, None], sc[:, :, None], rig, fps=30.0,
                    config=RunConfig(method=method), temporal=False, progress=False)  # fmt: skip
    assert "8 of 204 keypoints" in caplog.text
    assert np.nanmax(np.linalg.norm(poses.points[:, 0] - X, axis=-1)) < 1e-3
    assert (poses.num_views[:, 0, 3:5] == 2).all()


@pytest.mark.parametrize("cutoff", [15.0, 20.0, 100.0])
def test_cutoff_at_or_above_nyquist_is_refused(scene, cutoff):
    rig, _, kp, sc = scene
    with pytest.raises(InputError, match="Nyquist frequency fps / 2 = 15 Hz"):
        run(kp[:, :, None], sc[:, :, None], rig, fps=30.0,
            config=RunConfig(method="triangulate", cutoff=cutoff), progress=False)  # fmt: skip


@pytest.mark.parametrize(
    "field, value",
    [("cutoff", 0.0), ("cutoff", -3.0), ("max_gap", -1), ("min_score", 1.5),
     ("min_score", -0.1), ("max_error", -1.0), ("max_error", float("nan"))],
)  # fmt: skip
def test_impossible_run_config_values(field, value):
    with pytest.raises(ValueError, match=field):
        RunConfig(**{field: value})
