"""Tests of rmpl.benchmarks.foot_eval on a tiny fake MHP set with HALPE-26 targets and 2D."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from rmpl.benchmarks import foot_eval as fe
from rmpl.geometry.camera import look_at
from rmpl.skeleton import COCO17, HALPE26

W, H = 960, 720


def _fake_set(root: Path, meshes=3, views=4, halpe=True, seed=0) -> dict:
    """A fake ``rmpl generate`` directory: random bodies, cameras on a circle, 2D the exact
    projection except the small toes (missing, as MediaPipe gives none) and, with
    ``halpe``, the right heel 30 px off in view 0 of every mesh."""
    rng = np.random.default_rng(seed)
    J = 26 if halpe else 17
    X = rng.uniform(-0.3, 0.3, (meshes, J, 3)) + [0, 0, 1.0]
    K = np.array([[900.0, 0, W / 2], [0, 900, H / 2], [0, 0, 1]])
    Rs, ts = [], []
    for v in range(views):
        a = 2 * np.pi * v / views + 0.3
        R, t = look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 1.8]), np.array([0.0, 0, 1]))
        Rs.append(R)
        ts.append(t)
    R, t = np.stack(Rs), np.stack(ts)
    cam = np.einsum("vij,mkj->mvki", R, X) + t[None, :, None]  # (M, V, J, 3)
    uv = cam @ K.T
    kp = uv[..., :2] / uv[..., 2:]
    sc = np.full(kp.shape[:-1], 0.9)
    if halpe:
        sc[..., HALPE26.indices(["left_small_toe", "right_small_toe"])] = 0.0
        kp[:, 0, HALPE26.index("right_heel"), 0] += 30.0
    shard = {
        "joints3d": X.astype(np.float32),
        "keypoints": kp.astype(np.float32),
        "scores": sc.astype(np.float32),
        "K": np.broadcast_to(K, (meshes, views, 3, 3)).copy(),
        "R": np.broadcast_to(R, (meshes, views, 3, 3)).copy(),
        "t": np.broadcast_to(t, (meshes, views, 3)).copy(),
        "size": np.full((meshes, views, 2), [W, H], np.int32),
        "subject": np.array(["99"] * meshes),
        "clip": np.array(["fake"] * meshes),
        "frame": np.arange(meshes),
    }
    root.mkdir(parents=True)
    np.savez(root / "shard_00000.npz", **shard)
    names = HALPE26 if halpe else COCO17
    manifest = {
        "format": "rmpl.mhp.v1",
        "detector": "fake",
        "skeleton": names.name,
        "joints": list(names.joints),
    }
    (root / "manifest.json").write_text(json.dumps(manifest))
    return shard


def test_group_errors_by_hand():
    target = np.zeros((2, 26, 3))
    pred = np.repeat(target[:, None], 3, axis=1)  # (M=2, C=3, 26, 3)
    heel = HALPE26.index("left_heel")
    pred[0, :, heel, 2] = 0.02  # 20 mm off in mesh 0
    pred[1, 0, heel] = np.nan  # mesh 1, subset 0: no estimate
    target[1, HALPE26.index("right_heel")] = np.nan  # no target: not counted anywhere
    out = fe.group_errors(pred, target)
    # Heels: targets 2 x 3 (left) + 1 x 3 (right, mesh 0) = 9, estimated 8; errors: three
    # of 20 mm, five of 0 -> mean 60 / 8 = 7.5 mm; coverage 8 / 9.
    assert out["heels"][0] == pytest.approx(7.5)
    assert out["heels"][1] == pytest.approx(100 * 8 / 9)
    assert out["ankles"] == (0.0, 100.0)


def test_triangulation_on_a_fake_halpe_set(tmp_path):
    """Exact 2D: DLT recovers the feet it sees, misses the small toes, and the 30 px heel
    error in view 0 shows in the right heel only."""
    _fake_set(tmp_path / "set")
    d = fe.load_set(tmp_path / "set")
    assert d["target_set"] == d["kp_set"] == "halpe26" and d["targets"].shape == (3, 26, 3)

    class Nothing:  # a lifter that never answers, to test the triangulations alone
        skeleton = HALPE26

        def lift(self, kp, sc, rig, joints=None):
            raise AssertionError("not called")

    class Zero(Nothing):
        def lift(self, kp, sc, rig, joints=None):
            assert joints == "halpe26" and kp.shape[-2] == 26
            return type("R", (), {"points": np.zeros((26, 3))})()

    preds = fe.estimate(d, Zero(), 2)
    assert preds["DLT"].shape == (3, 6, 26, 3)  # 3 meshes, C(4, 2) = 6 subsets
    err = fe.group_errors(preds["DLT"], d["targets"])
    assert err["ankles"][0] < 1e-3 and err["ankles"][1] == 100.0
    assert err["big_toes"][0] < 1e-3 and np.isnan(err["small_toes"][0])
    assert err["small_toes"][1] == 0.0
    assert err["heels"][0] > 1.0  # the right heel's subsets with view 0 are off
    e = np.linalg.norm(preds["DLT"] - d["targets"][:, None], axis=-1)  # (3, 6, 26)
    assert e[..., HALPE26.index("left_heel")].max() < 1e-6
    with_view0 = [0, 1, 2]  # (0, 1), (0, 2), (0, 3) come first among the pairs
    right = e[..., HALPE26.index("right_heel")]
    assert (right[:, with_view0] > 0.005).all() and right[:, 3:].max() < 1e-6
    rmpl = fe.group_errors(preds["rmpl"], d["targets"])
    assert rmpl["small_toes"][1] == 100.0  # the model answers every joint


def test_foot_eval_main_with_a_26_joint_model(tmp_path, capsys):
    from rmpl.model.lifter import PRESETS, RMPL
    from rmpl.training.loop import save_checkpoint

    torch.manual_seed(0)
    model = tmp_path / "model"
    save_checkpoint(RMPL(PRESETS["tiny"].with_(num_joints=26, skeleton="halpe26")), model)
    _fake_set(tmp_path / "set")
    out = tmp_path / "foot.csv"
    argv = [str(tmp_path / "set"), "--views", "2", "4", "--model", str(model), "--csv", str(out)]
    assert fe.main(argv) == 0
    text = capsys.readouterr().out
    assert "| 4 | rmpl |" in text and "| 2 | robust |" in text
    assert "targets halpe26, 2D halpe26" in text and "(outputs halpe26)" in text
    assert "2 views, rmpl / DLT heels" in text and "4 views, rmpl heels" in text
    import csv

    rows = list(csv.DictReader(out.open()))
    assert [(r["views"], r["method"]) for r in rows] == [
        (k, m) for k in ("2", "4") for m in ("rmpl", "DLT", "robust")
    ]
    dlt4 = next(r for r in rows if r["views"] == "4" and r["method"] == "DLT")
    assert float(dlt4["ankles_mm"]) < 1.0 and float(dlt4["small_toes_coverage"]) == 0.0


def test_a_coco17_set_has_no_foot_targets(tmp_path, capsys):
    _fake_set(tmp_path / "set", halpe=False)
    assert fe.main([str(tmp_path / "set"), "--views", "3", "--limit", "2"]) == 0
    text = capsys.readouterr().out
    assert "targets coco17, 2D coco17" in text
    row = next(line for line in text.splitlines() if line.startswith("| 3 | DLT |"))
    assert [c.strip() for c in row.split("|")].count("—") == 3  # no foot targets


def test_bad_view_count(tmp_path, capsys):
    _fake_set(tmp_path / "set", meshes=1)
    assert fe.main([str(tmp_path / "set"), "--views", "5"]) == 2
    assert "--views" in capsys.readouterr().err
