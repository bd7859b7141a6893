"""The chained pipeline on a synthetic two-person scene, and `rmpl run` end to end."""

import numpy as np
import pytest
import torch

from rmpl.cli import main
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.io.poses import JointSource, load_poses
from rmpl.model.lifter import PRESETS, RMPL
from rmpl.pipeline.runner import RunConfig, run
from rmpl.training.loop import save_checkpoint


def two_walkers(T=40, views=4, seed=0):
    """Two people walking past each other, seen by `views` cameras; shuffled per view."""
    rng = np.random.default_rng(seed)
    K = np.array([[1000.0, 0, 640], [0, 1000, 480], [0, 0, 1]])
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views + 0.3
        R, t = look_at(np.array([5 * np.cos(a), 5 * np.sin(a), 2.5]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(1280, 960), name=f"c{v}"))
    rig = Rig(tuple(cams))
    body = rng.uniform(-0.25, 0.25, (17, 3)) * [1, 0.4, 0] + np.linspace(1.7, 0.1, 17)[:, None] * [
        0,
        0,
        1,
    ]
    s = np.linspace(-1, 1, T)[:, None]
    pos = np.stack(
        [np.concatenate([s, 0.3 + 0 * s, 0 * s], 1), np.concatenate([-s, -0.3 + 0 * s, 0 * s], 1)],
        1,
    )
    X = body[None, None] + pos[:, :, None]  # (T, 2, J, 3)
    kp = rig.project(X.reshape(T, 2 * 17, 3)).reshape(T, views, 2, 17, 2)
    kp = kp + rng.normal(0, 1.0, kp.shape)
    sc = np.full(kp.shape[:-1], 0.9)
    for t in range(T):  # detectors list people in any order
        for v in range(views):
            if rng.random() < 0.5:
                kp[t, v] = kp[t, v, ::-1]
    return rig, X, kp, sc


@pytest.mark.parametrize("method", ["triangulate", "robust"])
def test_two_people_associated_tracked_and_smoothed(method):
    rig, X, kp, sc = two_walkers()
    sc[10:13, :, :, 9] = 0  # a 3-frame gap of the left wrist in every view: interpolated
    kp[10:13, :, :, 9] = np.nan
    poses = run(kp, sc, rig, fps=30.0, config=RunConfig(method=method), progress=False)
    assert poses.points.shape[1] == 2
    # Each track follows one person all the way (no identity switch).
    for p in range(2):
        err = [np.linalg.norm(poses.points[:, p] - X[:, q], axis=-1) for q in range(2)]
        best = np.argmin([np.nanmean(e) for e in err])
        assert np.nanmax(err[best]) < 0.05
    flags = poses.flags
    assert (flags[10:13, :, 9] == JointSource.INTERPOLATED).all()
    assert (flags == JointSource.TRIANGULATED).mean() > 0.9


def test_run_cli_writes_outputs(tmp_path):
    rig, X, kp, sc = two_walkers(T=12, views=3)
    save_rig(rig, tmp_path / "calib.json")
    save_keypoints(
        Keypoints2D(kp, sc, "coco17", rig.names, np.arange(12), 25.0), tmp_path / "kp.npz"
    )
    torch.manual_seed(0)
    save_checkpoint(RMPL(PRESETS["tiny"]), tmp_path / "model")
    out = tmp_path / "out"
    code = main(
        [
            "run",
            "--calib",
            str(tmp_path / "calib.json"),
            "--keypoints",
            str(tmp_path / "kp.npz"),
            "--out",
            str(out),
            "--model",
            str(tmp_path / "model"),
        ]
    )
    assert code == 0
    for name in (
        "poses.npz",
        "poses.json",
        "poses.trc",
        "poses.c3d",
        "viewer.html",
        "skeleton.png",
    ):
        assert (out / name).is_file(), name
    poses = load_poses(out / "poses.npz")
    assert poses.points.shape[:2] == (12, 2)
    assert set(np.unique(poses.flags)) <= {0, 1, 3}


def test_run_cli_bad_formats(tmp_path, capsys):
    rig, X, kp, sc = two_walkers(T=3, views=2)
    save_rig(rig, tmp_path / "calib.json")
    save_keypoints(
        Keypoints2D(kp, sc, "coco17", rig.names, np.arange(3), 25.0), tmp_path / "kp.npz"
    )
    code = main(
        [
            "run",
            "--calib",
            str(tmp_path / "calib.json"),
            "--keypoints",
            str(tmp_path / "kp.npz"),
            "--out",
            str(tmp_path / "o"),
            "--formats",
            "trc,fbx",
        ]
    )
    assert code == 2
    assert "fbx" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_short_ghost_tracks_are_dropped():
    """A third 'person' seen in every view for 2 frames only (a false detection) makes a
    track of its own; min_track_frames removes it, 1 keeps it."""
    rig, X, kp, sc = two_walkers()
    T, V = kp.shape[:2]
    ghost = X[0, 0] + [0.0, 2.5, 0.0]  # 2.5 m away from both walkers
    g2d = rig.project(ghost)  # (V, 17, 2)
    kp3 = np.concatenate([kp, np.full((T, V, 1, 17, 2), np.nan)], axis=2)
    sc3 = np.concatenate([sc, np.zeros((T, V, 1, 17))], axis=2)
    kp3[20:22, :, 2] = g2d
    sc3[20:22, :, 2] = 0.9
    cfg = RunConfig(method="triangulate")
    poses = run(kp3, sc3, rig, fps=30.0, config=cfg, progress=False)
    assert poses.points.shape[1] == 2
    kept = run(
        kp3,
        sc3,
        rig,
        fps=30.0,
        config=RunConfig(method="triangulate", min_track_frames=1),
        progress=False,
    )
    assert kept.points.shape[1] == 3
    with pytest.raises(ValueError, match="min_track_frames"):
        RunConfig(min_track_frames=0)


def _true_person(kp, rig, X):
    """(T, V, N) which of the true people X (T, 2, J, 3) each 2D person of kp is."""
    proj = rig.project(X.reshape(len(X), -1, 3)).reshape(len(X), len(rig), 2, 1, -1, 2)
    d = np.nanmean(np.linalg.norm(kp[:, :, None] - proj, axis=-1), -1)  # (T, V, 2, N)
    return np.argmin(d, axis=2)


@pytest.mark.parametrize(
    "method, model", [("triangulate", "default"), ("robust", "default"), ("rmpl", "temporal")]
)
def test_membership_points_each_track_at_its_own_2d(method, model):
    """Detectors list people in any order and a view can miss one: each track's membership
    names, in every frame and view, the input's 2D of one and the same true person."""
    rig, X, kp, sc = two_walkers(T=30)
    who = _true_person(kp, rig, X)
    missed = who[7, 2, 0]
    kp[7, 2, 0], sc[7, 2, 0] = np.nan, 0  # view 2 misses its first-listed person in frame 7
    poses = run(kp, sc, rig, fps=30.0, config=RunConfig(method=method, model=model), progress=False)
    m = poses.membership
    assert m.shape == (30, 2, 4) and poses.camera_names == tuple(rig.names)
    identity = []
    for p in range(2):
        t, v = np.nonzero(m[:, p] >= 0)
        ids = who[t, v, m[t, p, v]]
        assert len(set(ids.tolist())) == 1  # never another person's 2D
        identity.append(ids[0])
    assert sorted(identity) == [0, 1]
    lost = identity.index(missed)
    assert m[7, lost, 2] == -1 and m[7, 1 - lost, 2] == 1  # the other one, listed second
    assert (m >= 0).sum() == 30 * 2 * 4 - 1


def test_robust_triangulation_records_the_keypoints_it_left_out():
    rig, X, kp, sc = two_walkers(T=12)
    kp[:, 0, :, 9] += 60.0  # view 0's left wrists are 60 px off: robust drops them
    robust = run(kp, sc, rig, fps=30.0, config=RunConfig(method="robust"), progress=False)
    assert (robust.views_excluded[:, :, 0] >= 1).all()
    assert robust.views_excluded[:, :, 1:].sum() < robust.views_excluded[:, :, 0].sum() / 4
    plain = run(kp, sc, rig, fps=30.0, config=RunConfig(method="triangulate"), progress=False)
    assert (plain.views_excluded == 0).all()  # plain DLT uses every keypoint


def _blend_files(tmp_path):
    """A 4-camera recording of two people through a single-person detector that picked A in
    cameras c0, c1 and B in c2, c3: one blended 3D person."""
    from tests.pipeline.test_consistency import make_rig, one_per_view, two_people

    rig = make_rig()
    sees = np.zeros((40, 4), int)
    sees[:, 2:] = 1
    kp, sc = one_per_view(two_people(), rig, sees)
    save_rig(rig, tmp_path / "calib.json")
    save_keypoints(
        Keypoints2D(kp, sc, "coco17", rig.names, np.arange(40), 25.0), tmp_path / "kp.npz"
    )
    return ["run", "--calib", str(tmp_path / "calib.json"), "--keypoints",
            str(tmp_path / "kp.npz"), "--method", "triangulate", "--no-pictures", "--out",
            str(tmp_path / "out")]  # fmt: skip


def test_run_cli_reports_a_blend(tmp_path, caplog):
    import json
    import logging

    with caplog.at_level(logging.INFO):
        main(_blend_files(tmp_path))
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["exit_code"] == 3 and report["failed_people"] == [0]
    assert len({d["camera"] for d in report["disagreements"]}) >= 2  # one pair or the other
    assert any("THE VIEWS DISAGREE" in r.getMessage() for r in caplog.records)
    assert load_poses(tmp_path / "out" / "poses.json").view_status is not None


def test_run_cli_exits_3_on_a_blend(tmp_path):
    assert main(_blend_files(tmp_path)) == 3
