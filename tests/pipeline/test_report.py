"""The run report: known reprojection errors, view counts, gaps and heights; report.md/json
and the summary name the disagreeing view, person and frames; a blend fails with status 3;
the report is committed with the other outputs."""

import json
import logging
import warnings
from pathlib import Path

import numpy as np
import pytest

from rmpl.anthropometry import estimate_height
from rmpl.io.poses import JointSource, Poses3D, ViewStatus, load_poses
from rmpl.pipeline import outputs
from rmpl.pipeline.inputs import Inputs
from rmpl.pipeline.report import build_report
from rmpl.pipeline.runner import RunConfig, run
from tests.pipeline.test_consistency import FRAMES, make_rig, one_per_view, two_people


def _inputs(rig, kp, sc, frames=FRAMES):
    return Inputs(rig, kp, sc, np.asarray(frames), 25.0)


def test_known_reprojection_errors_view_counts_gaps_and_height():
    """Every 2D keypoint lies exactly (3, 4) px from its joint's projection: 5 px
    everywhere, and px * depth / focal in mm. Three of four views used: one excluded."""
    rig = make_rig()
    X = two_people(T=40)[:, :1]  # (T, 1, J, 3): person A alone
    T = len(X)
    kp = rig.project(X[:, 0])[:, :, None] + np.array([3.0, 4.0])  # (T, V, 1, J, 2)
    sc = np.ones(kp.shape[:-1])
    flags = np.full((T, 1, 17), int(JointSource.TRIANGULATED))
    flags[5:8, 0, 9] = JointSource.INTERPOLATED  # a 3-frame gap of the left wrist, filled
    poses = Poses3D(
        X.copy(),
        flags=flags,
        num_views=np.full((T, 1, 17), 3),
        frames=FRAMES,
        fps=25.0,
        membership=np.zeros((T, 1, 4), int),
        camera_names=rig.names,
    )
    r = build_report(poses, _inputs(rig, kp, sc))
    depth = np.einsum("vij,tkj->tvki", rig.R, X[:, 0])[..., 2] + rig.t[None, :, None, 2]
    mm = 5 * depth / 1000.0 * 1000  # (T, V, J), focal 1000 px
    for j, row in enumerate(r.joints):
        m = np.ones(T, bool)
        if j == 9:
            m[5:8] = False  # gap-filled frames are not measured
        assert row["reprojection_px_median"] == pytest.approx(5.0, abs=0.01)
        assert row["reprojection_px_p90"] == pytest.approx(5.0, abs=0.01)
        assert row["reprojection_mm_median"] == pytest.approx(np.median(mm[m, :, j]), abs=0.01)
        assert row["reprojection_mm_p90"] == pytest.approx(np.percentile(mm[m, :, j], 90), abs=0.01)
        assert (row["views_with_2d"], row["views_used"], row["views_excluded"]) == (4, 3, 1)
        assert row["measured"] == m.sum()
    [person] = r.people
    assert person["frames"] == T and person["frames_gap_filled"] == 3
    assert person["joints_gap_filled"] == 3
    assert person["height_m"] == pytest.approx(estimate_height(X[:, 0]), abs=1e-3)
    assert person["height_m"] == pytest.approx(1.8, rel=0.02)  # built at 1.80 m
    assert r.poses.heights[0] == pytest.approx(person["height_m"], abs=1e-3)
    assert [c["camera"] for c in r.cameras] == rig.names
    assert all(c["agrees"] == T and c["missed"] == 0 for c in r.cameras)
    assert r.exit_code == 0 and r.disagreements == []


def _write(tmp_path, sees, caplog, name="out"):
    rig = make_rig()
    kp, sc = one_per_view(two_people(), rig, sees)
    poses = run(kp, sc, rig, frames=FRAMES, fps=25.0, config=RunConfig(method="triangulate"),
                progress=False)  # fmt: skip
    out = tmp_path / name
    caplog.clear()
    with caplog.at_level(logging.INFO):
        report = outputs.write_all(poses, _inputs(rig, kp, sc), out, ["npz", "json"], False)
    return out, report


def test_a_view_seeing_someone_else_is_named_in_the_report_and_the_summary(tmp_path, caplog):
    sees = np.zeros((40, 4), int)
    sees[10:30, 3] = 1  # c3 shows the other person in frames 110-129
    out, report = _write(tmp_path, sees, caplog)
    assert report.exit_code == 0  # 20 of 40 frames: not most
    doc = json.loads((out / "report.json").read_text())
    assert doc["format"] == "rmpl.report" and doc["exit_code"] == 0
    [d] = doc["disagreements"]
    assert (d["person"], d["camera"], d["frames"], d["ranges"]) == (0, "c3", 20, [[110, 129]])
    assert "threshold" in doc["check"] and doc["definitions"]["disagrees"]
    md = (out / "report.md").read_text()
    assert "| 0 | c3 | 20 | 110-129 |" in md
    logged = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any("person 0" in w and "c3 in 20 frames (110-129)" in w for w in logged)
    assert not any("THE VIEWS DISAGREE" in w for w in logged)
    poses = load_poses(out / "poses.json")  # the JSON marks the views, and the joints
    assert (poses.view_status[10:30, 0, 3] == ViewStatus.DISAGREES).all()
    assert (poses.view_status[:10, 0] == ViewStatus.AGREES).all()
    suspect = np.array(json.loads((out / "poses.json").read_text())["suspect"])
    assert suspect[10:30].any(-1).all() and not suspect[:10].any()
    assert poses.heights[0] > 0 and load_poses(out / "poses.npz").membership is not None


def test_a_blend_fails_loudly_and_a_clean_run_stays_quiet(tmp_path, caplog):
    sees = np.zeros((40, 4), int)
    sees[:, 2:] = 1  # two cameras on each person: one 3D person, a blend
    out, report = _write(tmp_path, sees, caplog, "blend")
    assert report.exit_code == 3 and report.failed == [0]
    assert json.loads((out / "report.json").read_text())["failed_people"] == [0]
    assert "WARNING: the views disagree on person(s) 0" in (out / "report.md").read_text()
    assert any("THE VIEWS DISAGREE" in r.getMessage() for r in caplog.records)

    out, report = _write(tmp_path, np.zeros((40, 4), int), caplog, "clean")
    assert report.exit_code == 0
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert "None." in (out / "report.md").read_text()  # no disagreement


def test_the_report_is_committed_with_the_other_outputs(tmp_path, caplog, monkeypatch):
    """A failure while writing the report leaves the previous complete set."""
    out, _ = _write(tmp_path, np.zeros((40, 4), int), caplog)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert {"report.md", "report.json", "poses.npz", "poses.json"} <= set(before)

    def boom(report, folder):
        (Path(folder) / "report.md").write_text("half")
        raise OSError("disk full")

    monkeypatch.setattr("rmpl.pipeline.report.write_report", boom)
    with pytest.raises(OSError, match="disk full"):
        _write(tmp_path, np.zeros((40, 4), int), caplog)
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before


def test_without_membership_several_people_are_not_checked(tmp_path, caplog):
    """Poses from elsewhere (no membership) with several 2D people per view: the report is
    still written, says why there are no per-view figures, and does not fail."""
    rig = make_rig()
    X = two_people()
    kp = rig.project(X.reshape(40, -1, 3)).reshape(40, 4, 2, 17, 2)
    poses = Poses3D(X, frames=FRAMES, fps=25.0)
    report = build_report(poses, _inputs(rig, kp, np.ones(kp.shape[:-1])))
    assert report.consistency is None and report.exit_code == 0 and report.cameras == []
    assert "which 2D person" in report.to_markdown()
    assert report.people[1]["height_m"] == pytest.approx(1.6, rel=0.03)


def test_the_embedded_example_flags_exactly_the_grossly_wrong_detections():
    """The embedded 4-camera walk (an anny body, MediaPipe's 2D on renders): the views that
    disagree are exactly those whose 2D lies, on median over joints, more than 0.2 of the
    person's size from the projected ground truth (MediaPipe's gross misses); the height from
    the lifted 3D is within 3% of the height from the ground truth's joints."""
    import rmpl
    from rmpl.evaluate.example import EXAMPLE

    rig = rmpl.load_rig(EXAMPLE / "calibration.toml")
    kp = rmpl.load_keypoints(EXAMPLE / "keypoints.json")
    truth = np.load(EXAMPLE / "ground_truth.npz")["points"][:, 0].astype(float)
    poses = run(kp.keypoints, kp.scores, rig, kp.frames, kp.fps, RunConfig(), progress=False)
    report = build_report(poses, Inputs(rig, kp.keypoints, kp.scores, kp.frames, kp.fps))
    c = report.consistency
    err = np.linalg.norm(kp.keypoints[:, :, 0] - rig.project(truth), axis=-1)  # (T, V, J)
    with warnings.catch_warnings():  # views without 2D in a frame: all-NaN medians
        warnings.simplefilter("ignore", RuntimeWarning)
        gross = np.nanmedian(np.where(kp.scores[:, :, 0] > 0, err, np.nan), -1) > 0.2 * c.size[:, 0]
    compared = np.isin(c.status[:, 0], [ViewStatus.AGREES, ViewStatus.DISAGREES])
    np.testing.assert_array_equal(
        (c.status[:, 0] == ViewStatus.DISAGREES)[compared], gross[compared]
    )
    assert gross[compared].sum() < 0.1 * compared.sum() and report.exit_code == 0
    assert report.people[0]["height_m"] == pytest.approx(estimate_height(truth), rel=0.03)


def test_one_camera_is_not_reported_as_agreeing():
    """Nothing to compare (one camera): the report says the check did not run, not that every
    view agrees."""
    from rmpl.geometry.camera import Rig
    from rmpl.pipeline.report import verdict_lines

    rig = make_rig()
    one = Rig((rig[0],))
    X = two_people()[:, :1]  # (T, 1, 17, 3)
    kp = one.project(X.reshape(len(X), -1, 3)).reshape(len(X), 1, 1, 17, 2)
    poses = Poses3D(X, frames=FRAMES, fps=25.0, membership=np.zeros((len(X), 1, 1), int))
    report = build_report(poses, _inputs(one, kp, np.ones(kp.shape[:-1])))
    text = " ".join(verdict_lines(report))
    assert "every view agrees" not in text and "not checked" in text
    assert report.to_json()["check"]["done"] is False
