"""Sequence methods: per-frame estimates tracked over time, then filtered or lifted."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rmpl.errors import InputError
from rmpl.evaluate.registry import parse_methods
from rmpl.evaluate.sequences import dataset_fps, is_sequence_method, make_sequence_method
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.model.lifter import PRESETS, RMPL
from rmpl.model.temporal import TemporalConfig, TemporalRMPL
from rmpl.pipeline.tracklift import pieces, tracks_2d
from rmpl.training.temporal import save_temporal


def _rig(views=3) -> Rig:
    K = np.array([[900.0, 0, 480], [0, 900, 360], [0, 0, 1]])
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views
        R, t = look_at(np.array([5 * np.cos(a), 5 * np.sin(a), 2.0]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(960, 720), name=f"cam{v}"))
    return Rig(tuple(cams))


def _two_people(T=30, views=3, seed=0):
    """Two people walking past each other; per-frame rows in shuffled order, as association
    gives them. Returns kp (M, V, J, 2), sc, frame (M,), who (M,), the 3D (T, 2, J, 3), rig."""
    rng = np.random.default_rng(seed)
    rig = _rig(views)
    body = rng.uniform(-0.25, 0.25, (17, 3)) + [0, 0, 1.0]
    t = np.arange(T)[:, None] / 25
    X = np.stack([body + np.c_[1.2 * t - 1.0, 0 * t + 0.6, 0 * t][:, None],
                  body + np.c_[1.0 - 1.2 * t, 0 * t - 0.6, 0 * t][:, None]], 1)  # fmt: skip
    kp, sc, frame, who = [], [], [], []
    for f in range(T):
        for p in rng.permutation(2):
            kp.append(rig.project(X[f, p]) + rng.normal(0, 0.5, (views, 17, 2)))
            sc.append(np.full((views, 17), 0.9))
            frame.append(f)
            who.append(p)
    return np.array(kp), np.array(sc), np.array(frame), np.array(who), X, rig


@pytest.mark.parametrize("name", ["triangulate+filter", "robust+filter"])
def test_filter_methods_track_two_people_without_identity(name):
    kp, sc, frame, who, X, rig = _two_people()
    method = make_sequence_method(name)
    pred, at = method(kp, sc, frame, 30, rig, 25.0)
    assert sorted(np.bincount(at).tolist()) == [2] * 30  # two tracks, every frame
    for f in range(30):
        d = np.linalg.norm(pred[at == f][:, None] - X[f][None], axis=-1).mean(-1)  # (2, 2)
        assert d.min(1).max() < 0.02  # each prediction lies on one person


def test_temporal_method_from_a_checkpoint_path(tmp_path):
    torch.manual_seed(0)
    m = TemporalRMPL(RMPL(PRESETS["tiny"]), TemporalConfig(dim=16, depth=1, window=8))
    save_temporal(m, tmp_path / "temporal")
    spec = f"rmpl:{tmp_path / 'temporal'}"
    assert is_sequence_method(spec) and not is_sequence_method("rmpl:default")
    methods = parse_methods(f"triangulate,{spec}")
    kp, sc, frame, who, X, rig = _two_people(T=20)
    pred, at = methods[spec](kp, sc, frame, 20, rig, 25.0)
    assert len(pred) == 40 and np.isfinite(pred).all()


def test_empty_input_and_unknown_names():
    method = make_sequence_method("triangulate+filter")
    pred, at = method(np.zeros((0, 3, 17, 2)), np.zeros((0, 3, 17)), np.zeros(0, int), 5,
                      _rig(), 25.0)  # fmt: skip
    assert pred.shape == (0, 17, 3) and at.shape == (0,)
    with pytest.raises(InputError, match="rmpl:temporal"):
        parse_methods("magic+filter")


def test_fps_defaults():
    assert dataset_fps("shelf", None) == 25.0 and dataset_fps("h36m", None) == 50.0
    assert dataset_fps("shelf", 12.5) == 12.5


def test_pieces_and_tracks_2d():
    assert pieces(np.zeros(4, bool), 3) == []
    assert pieces(np.array([1, 0, 0, 0, 0, 1], bool), 3) == [(0, 1), (5, 6)]
    assert pieces(np.array([1, 0, 0, 0, 1], bool), 3) == [(0, 5)]

    class P:
        def __init__(self, n):
            self.keypoints = np.arange(n * 2 * 17 * 2, dtype=float).reshape(n, 2, 17, 2)
            self.scores = np.ones((n, 2, 17))

        def __len__(self):
            return len(self.keypoints)

    people = [P(2), P(1)]
    kp, sc = tracks_2d(people, np.array([[1, 0], [-1, 0]]))
    assert np.array_equal(kp[0, 0], people[0].keypoints[1])
    assert np.isnan(kp[1, 0]).all() and (sc[1, 0] == 0).all()
    assert np.array_equal(kp[1, 1], people[1].keypoints[0])


def test_sequence_methods_are_refused_without_time(tmp_path, capsys):
    from rmpl.cli import main

    code = main(["evaluate", "--dataset", "synthetic", "--root", str(tmp_path / "bank.npz"),
                 "--methods", "triangulate,triangulate+filter"])  # fmt: skip
    assert code != 0
    assert "--methods" in capsys.readouterr().err


def test_a_jump_in_frame_numbers_starts_a_new_stretch():
    """Campus-like parts (two frame ranges) and clips are tracked and filtered apart."""
    from rmpl.evaluate.sequences import stretches

    kp, sc, frame, who, X, rig = _two_people(T=30)
    numbers = np.r_[np.arange(15), np.arange(100, 115)]
    method = make_sequence_method("triangulate+filter")
    pred, at = method(kp, sc, frame, 30, rig, 25.0, numbers)
    assert sorted(np.bincount(at).tolist()) == [2] * 30
    assert stretches(30, numbers) == [(0, 15, 1), (15, 30, 1)]
    clips = np.array(["a"] * 10 + ["b"] * 20)
    assert stretches(30, np.arange(30), clips) == [(0, 10, 1), (10, 30, 1)]
    assert stretches(0) == [] and stretches(3) == [(0, 3, 1)]
