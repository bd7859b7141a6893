"""Identities through ``rmpl run``: the tracks written, the report's identity table,
``--people``, ``--pose2sim-min-frames``, and bad input (nobody anywhere, a view with
nobody)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.pipeline.runner import RunConfig, run

from .test_pipeline import two_walkers


def _with_gap(T=80, views=4, gap=range(30, 50)):
    """Two people walking past each other; the first is seen by no view in ``gap`` (longer
    than the tracker's 10 missed frames)."""
    rig, X, kp, sc = two_walkers(T=T, views=views)
    for t in gap:  # the detectors list people in any order: find the first person's slot
        for v in range(views):
            proj = rig.cameras[v].project(X[t, 0])
            slot = int(np.argmin([np.nanmean(np.abs(kp[t, v, n] - proj)) for n in range(2)]))
            kp[t, v, slot], sc[t, v, slot] = np.nan, 0.0
    return rig, X, kp, sc


def _save(tmp_path, rig, kp, sc, fps=25.0):
    save_rig(rig, tmp_path / "calib.json")
    T = len(kp)
    save_keypoints(Keypoints2D(kp, sc, "coco17", rig.names, np.arange(T), fps), tmp_path / "kp.npz")
    return ["--calib", str(tmp_path / "calib.json"), "--keypoints", str(tmp_path / "kp.npz")]


def test_run_relinks_a_person_across_a_gap():
    rig, X, kp, sc = _with_gap()
    cfg = RunConfig(method="triangulate")
    poses = run(kp, sc, rig, fps=25.0, config=cfg, progress=False)
    assert poses.points.shape[1] == 2
    rec = poses.identity
    assert rec["fragments"] == 3 and [m["kind"] for m in rec["merges"]] == ["relinked"]
    for p in range(2):  # each track follows one person
        err = [np.nanmean(np.linalg.norm(poses.points[:, p] - X[:, q], axis=-1)) for q in range(2)]
        assert min(err) < 0.05


def test_cli_identity_table_and_pose2sim_min_frames(tmp_path):
    rig, X, kp, sc = _with_gap()
    args = _save(tmp_path, rig, kp, sc)
    out = tmp_path / "out"
    common = ["--method", "triangulate", "--max-gap", "5", "--no-pictures", "--out", str(out)]
    assert main(["run", *args, *common, "--people", "2", "--pose2sim-min-frames", "70"]) == 0
    report = json.loads((out / "report.json").read_text())
    identity = report["identity"]
    assert identity["tracks"] == 2 and identity["settings"]["people"] == 2
    assert [row["frames"] for row in identity["rows"]] == [60, 80]
    assert all(row["height_m"] for row in identity["rows"])
    assert "## Identities" in (out / "report.md").read_text()
    # the person seen in 60 frames gets no Pose2Sim files of its own, the other does
    assert sorted(p.name for p in (out / "pose-3d").iterdir()) == ["poses_p1.c3d", "poses_p1.trc"]


def test_a_view_with_nobody_still_gives_both_people():
    rig, X, kp, sc = two_walkers(T=30, views=4)
    kp[:, 2], sc[:, 2] = np.nan, 0.0  # camera 2 sees nobody
    poses = run(kp, sc, rig, fps=25.0, config=RunConfig(method="triangulate"), progress=False)
    assert poses.points.shape[1] == 2
    assert (poses.membership[:, :, 2] == -1).all()


def test_nobody_anywhere_is_one_clear_line(tmp_path, capsys):
    rig, X, kp, sc = two_walkers(T=5, views=3)
    kp[:], sc[:] = np.nan, 0.0
    args = _save(tmp_path, rig, kp, sc)
    code = main(["run", *args, "--method", "triangulate", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "scores" in err[0]
    assert not (tmp_path / "o").exists()


def test_people_zero_is_one_clear_line(tmp_path, capsys):
    rig, X, kp, sc = two_walkers(T=5, views=3)
    args = _save(tmp_path, rig, kp, sc)
    with pytest.raises(SystemExit) as e:
        main(["run", *args, "--people", "0", "--out", str(tmp_path / "o")])
    assert e.value.code == 2
    assert "argument --people: expected an integer >= 1, got 0" in capsys.readouterr().err
