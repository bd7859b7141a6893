"""The output side of rmpl run with a HALPE-26 lifter (COCO-17, head top, neck, mid-hip and six
foot points): every file has 26 joints with their names (NPZ, JSON, TRC, C3D read back with
the ``c3d`` package, Pose2Sim's HALPE_26 markers, the report's rows); the one-camera path
moves every joint with its depth; tracking decides on the COCO-17 joints; a COCO-17 model
still answers in COCO-17. The models are random (untrained): the plumbing is tested, not
the accuracy."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import c3d
import numpy as np
import pytest

from rmpl.io.pose2sim import HALPE26_MARKERS
from rmpl.io.poses import load_poses
from rmpl.skeleton import HALPE26, embed, embed_scores
from tests.io.test_pose2sim import read_trc

EXAMPLE = Path(__file__).resolve().parents[2] / "src/rmpl/examples/walk"


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> dict[str, Path]:
    """A random HALPE-26 per-frame checkpoint and a temporal one around it."""
    import torch

    from rmpl.model.lifter import PRESETS, RMPL
    from rmpl.model.temporal import TemporalConfig, TemporalRMPL
    from rmpl.training.loop import save_checkpoint
    from rmpl.training.temporal import save_temporal

    root = tmp_path_factory.mktemp("halpe26_models")
    torch.manual_seed(0)
    frame = RMPL(PRESETS["tiny"].with_(num_joints=26, skeleton="halpe26"))
    save_checkpoint(frame, root / "frame")
    save_temporal(TemporalRMPL(frame, TemporalConfig(window=8)), root / "temporal")
    return {"frame": root / "frame", "temporal": root / "temporal"}


def _run(out: Path, *extra: str) -> int:
    from rmpl.cli import main

    return main(
        ["run", "--calib", str(EXAMPLE / "calibration.toml"), "--keypoints",
         str(EXAMPLE / "keypoints.json"), "--out", str(out), "--no-pictures",
         "--formats", "npz,json,trc,c3d,bvh", *extra]
    )  # fmt: skip


def _c3d_labels(path: Path) -> list[str]:
    with open(path, "rb") as f, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = c3d.Reader(f)
        frames = list(r.read_frames())
        return [s.strip() for s in r.point_labels], len(frames)


@pytest.mark.parametrize("kind", ["frame", "temporal"])
def test_rmpl_run_writes_26_named_joints_everywhere(models, tmp_path, kind):
    out = tmp_path / kind
    assert _run(out, "--model", str(models[kind])) == 0
    names = list(HALPE26.joints)
    for name in ("poses.npz", "poses.json", "poses.trc"):
        poses = load_poses(out / name)
        assert poses.skeleton == "halpe26" and poses.points.shape[1:] == (1, 26, 3), name
        assert np.isfinite(poses.points[:, 0, 17:]).any()  # feet and head top estimated
    doc = json.loads((out / "poses.json").read_text())
    assert doc["joints"] == names
    labels, frames = _c3d_labels(out / "poses.c3d")
    assert labels == names and frames == 60
    assert (out / "poses.bvh").is_file()
    p2s = read_trc(out / "pose-3d" / "poses_p0.trc")
    assert p2s["markers"] == list(HALPE26_MARKERS)
    labels, _ = _c3d_labels(out / "pose-3d" / "poses_p0.c3d")
    assert labels == list(HALPE26_MARKERS)
    report = json.loads((out / "report.json").read_text())
    rows = {row["joint"]: row for row in report["joints"]}
    assert list(rows) == names
    # the example's 2D is COCO-17: the new joints have no 2D, so no reprojection error
    assert rows["left_heel"]["views_with_2d"] == 0
    assert rows["left_heel"]["reprojection_px_median"] is None
    assert rows["left_ankle"]["views_with_2d"] > 2
    assert rows["left_ankle"]["reprojection_px_median"] is not None
    assert report["people"][0]["height_m"] is not None
    if kind == "temporal":
        assert rows["left_heel"]["predicted_error_radius_mm"] is not None


def test_a_coco17_model_still_writes_coco17(tmp_path):
    out = tmp_path / "coco"
    assert _run(out, "--model", "default", "--method", "rmpl") == 0
    poses = load_poses(out / "poses.npz")
    assert poses.skeleton == "coco17" and poses.points.shape[2] == 17
    assert len(read_trc(out / "pose-3d" / "poses_p0.trc")["markers"]) == 19  # COCO_17's


def _example_inputs():
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    return load_inputs(
        InputSpec(
            calib=str(EXAMPLE / "calibration.toml"), keypoints=[str(EXAMPLE / "keypoints.json")]
        )
    )


def test_halpe26_2d_with_a_coco17_model_and_triangulation():
    """2D in HALPE-26 (here COCO-17 embedded, the new joints missing): the COCO-17 lifter
    answers in COCO-17 with the same points as from the COCO-17 2D; triangulation keeps the
    2D's joint set."""
    from rmpl.pipeline.runner import RunConfig, run

    inp = _example_inputs()
    kp26 = embed(inp.keypoints, "coco17", "halpe26")
    sc26 = embed_scores(inp.scores, "coco17", "halpe26")
    cfg = RunConfig(method="rmpl", model="default")
    a = run(inp.keypoints[:10], inp.scores[:10], inp.rig, fps=20.0, config=cfg, progress=False)
    b = run(kp26[:10], sc26[:10], inp.rig, fps=20.0, config=cfg, progress=False, joints="halpe26")
    assert b.skeleton == "coco17"
    np.testing.assert_allclose(b.points, a.points, atol=1e-9)
    tri = run(kp26[:10], sc26[:10], inp.rig, fps=20.0, progress=False,
              config=RunConfig(method="robust"), joints="halpe26")  # fmt: skip
    assert tri.skeleton == "halpe26" and tri.points.shape[2] == 26
    assert np.isnan(tri.points[:, :, 17:]).all()  # no 2D, no triangulated feet


@pytest.mark.parametrize("cues", [("floor", "size"), ("floor", "size", "time")])
def test_one_camera_moves_every_joint_with_the_depth(cues):
    """Per frame the answer is C + s (X - C) of the lifter's own 26-joint X, one s for all
    joints: the cues read COCO-17 joints, the feet and head top move with them. (A stand-in
    lifter: the shipped COCO-17 one plus nine points hung off its joints, since a random
    network puts every joint of a single view at one point.)"""
    from rmpl.geometry.camera import Rig
    from rmpl.geometry.floor import convention_floor
    from rmpl.inference import Lifter
    from rmpl.pipeline.monocular import MonocularConfig, monocular_people
    from rmpl.pipeline.runner import RunConfig

    inp = _example_inputs()
    rig = Rig((inp.rig[0],))
    coco = Lifter.from_pretrained("default")
    offsets = np.random.default_rng(0).normal(0, 0.1, (9, 3))
    raw = {}

    def lift26(kp, sc, r):
        res = coco.lift(kp, sc, r, up=np.asarray(cfg.up))
        extra = res.points[..., [0, 5, 11, 15, 16, 15, 16, 15, 16], :] + offsets
        pts = np.concatenate([res.points, extra], axis=-2)
        for x in pts:
            raw[x[:17].tobytes()] = x
        return pts, np.concatenate([res.num_views, res.num_views[..., :9]], -1)

    lift26.skeleton = "halpe26"
    T = 20
    kp, sc = inp.keypoints[:T, :1, 0], inp.scores[:T, :1, 0]  # (T, 1, 17, 2)
    floor = convention_floor(rig.R, rig.centers, None)
    cfg = RunConfig(method="rmpl", model="default", up=tuple(floor.n))
    res = monocular_people(
        kp, sc, np.arange(T), T, rig, 20.0, floor, MonocularConfig(cues=cues), cfg, lift26
    )
    assert res.skeleton == "halpe26" and res.points.shape == (T, 1, 26, 3)
    C = rig.centers[0]
    X = res.points[:, 0] - C
    lifted = coco.lift(kp, sc, rig, up=np.asarray(cfg.up)).points
    own = np.stack([raw[x.tobytes()] for x in lifted]) - C  # the stand-in's 26 joints
    s = np.linalg.norm(X, axis=-1) / np.linalg.norm(own, axis=-1)  # (T, 26)
    assert np.isfinite(s).all() and np.ptp(s) > 1e-3  # depths were changed, not kept
    np.testing.assert_allclose(s, s[:, :1].repeat(26, 1), rtol=1e-9)
    np.testing.assert_allclose(X, s[..., None] * own, atol=1e-9)


def test_tracking_decides_on_the_coco17_joints():
    """Two people whose extra joints (17-25) are swapped between them: the tracks follow
    the COCO-17 joints, as with the 17 joints alone."""
    from rmpl.pipeline.runner import RunConfig, track_index

    rng = np.random.default_rng(0)
    T = 8
    a = rng.normal(0, 0.1, (26, 3))
    b = a + [2.0, 0.0, 0.0]
    frames = []
    for t in range(T):
        pa, pb = a + [0.05 * t, 0, 0], b - [0.05 * t, 0, 0]
        pa[17:], pb[17:] = pb[17:].copy(), pa[17:].copy()  # misleading feet
        frames.append(np.stack([pa, pb] if t % 2 else [pb, pa]))
    cfg = RunConfig(min_track_frames=1)
    index26, _ = track_index(frames, cfg)
    index17, _ = track_index([f[:, :17] for f in frames], cfg)
    np.testing.assert_array_equal(index26, index17)
    assert index26.shape[1] == 2
