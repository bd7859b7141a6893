"""``rmpl evaluate`` on the real fixtures (../shared/data) and on tiny synthetic inputs.

Most runs use the fast methods (triangulate, robust); one runs the shipped RMPL model.
"""

from __future__ import annotations

import csv
import logging

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.errors import InputError
from rmpl.evaluate.evalset import gt_coco, load_eval_set, reprojection_check
from rmpl.evaluate.harness import EvalConfig, evaluate, evaluate_poses, view_subsets
from rmpl.evaluate.methods import make_method
from rmpl.evaluate.scoring import pose_metrics
from rmpl.evaluate.tables import results_rows
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.synth.cameras import sphere_cameras
from rmpl.synth.motion import PoseSet, save_pose_set

FAST = "triangulate,robust"


def _rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _run(*argv) -> int:
    return main(["evaluate", *map(str, argv)])


@pytest.fixture
def fixtures(shared_data):
    root = shared_data / "fixtures"
    if not root.is_dir():
        pytest.skip(f"{root} not found")
    return root


# --- the loaders through rmpl evaluate, on the real fixtures ---------------------------

# Median distance (px) allowed between the projected ground truth and the 2D input; the
# measured values are in the comments of each case.
LOADER_CASES = [
    # (dataset, folder, extra options, views, joints scored, people, max median px)
    ("shelf", "shelf", ["--2d", "annotations"], 5, 12, 4, 0.5),  # measured ~0.03 px
    ("campus", "campus", ["--2d", "annotations"], 3, 12, 3, 1.5),  # whole-pixel labels
    ("panoptic", "panoptic_body3d", [], 5, 17, 3, 15.0),  # noise model, ~5 px
    ("h36m", "h36m", [], 4, 13, 1, 10.0),  # MMPose detections, 1.5-6.8 px
]


@pytest.mark.shared
@pytest.mark.parametrize("dataset,folder,extra,views,joints,people,max_px", LOADER_CASES)
def test_loader_through_evaluate(
    fixtures, tmp_path, dataset, folder, extra, views, joints, people, max_px
):
    root = fixtures / folder
    two_d = extra[1] if extra else "auto"
    evset = load_eval_set(dataset, root, two_d=two_d)
    # The source in one word (results.csv's 2d_source): Panoptic has no detections.
    auto = "detections" if dataset == "h36m" else "projection"
    assert evset.two_d == (two_d if extra else auto)
    # Shapes: every part has V cameras, 2D (T, V, N, 17, 2) and ground truth (T, P, J, 3).
    assert evset.num_views == views
    for part in evset.parts:
        T = len(part)
        assert part.keypoints.shape[:2] == (T, views) and part.keypoints.shape[3:] == (17, 2)
        assert part.scores.shape == part.keypoints.shape[:-1]
        assert part.gt.shape[0] == T and part.gt.shape[1] <= people
    # Units: metres. Upper-arm and thigh lengths of adults, wherever annotated.
    for part in evset.parts:
        X = gt_coco(part)
        for a, b in ((5, 7), (6, 8), (11, 13), (12, 14)):
            d = np.linalg.norm(X[..., a, :] - X[..., b, :], axis=-1)
            d = d[np.isfinite(d)]
            assert d.size and np.all((d > 0.2) & (d < 0.6)), (dataset, a, b, d)
    # The ground truth projected with the calibration lands on the 2D.
    med, p90, n = reprojection_check(evset)
    assert n > 0 and med < max_px, (dataset, med, p90)

    out = tmp_path / dataset
    assert (
        _run(
            "--dataset",
            dataset,
            "--root",
            root,
            "--methods",
            FAST,
            "--views",
            "all",
            "--out",
            out,
            *extra,
        )
        == 0
    )
    rows = _rows(out / "results.csv")
    assert [r["method"] for r in rows] == ["triangulate", "robust"]
    assert all(r["views"] == f"{views} views" for r in rows)
    per_joint = _rows(out / "per_joint.csv")
    assert len(per_joint) == 2 * joints
    group = "per_clip.csv" if dataset == "h36m" else "per_person.csv"
    assert _rows(out / group)
    for png in ("joint_errors_box.png", "joint_mpjpe_bar.png"):
        assert (out / png).read_bytes()[:4] == b"\x89PNG"
    text = (out / "results.md").read_text()
    assert "association protocol" in text and "ground truth projected onto the 2D" in text
    assert f"--dataset {dataset}" in text  # the command that made the table
    if dataset in ("shelf", "campus"):
        assert "PCP" in text and "pcp_mean" in rows[0]
    if dataset == "panoptic":
        assert "noise model" in text and "NOT a real detector" in text
    if dataset == "h36m":
        # One view per frame in the fixture: triangulation cannot, so coverage is 0.
        assert float(rows[0]["coverage"]) == 0.0


@pytest.mark.shared
def test_annotation_2d_triangulates_to_millimetres(fixtures):
    """Exact 2D labels + the dataset's calibration -> a few mm: calibration, units and
    joint order of the loader are consistent (metres, Shelf-14 -> COCO-17 by name)."""
    evset = load_eval_set("shelf", fixtures / "shelf", two_d="annotations")
    ev = evaluate(
        evset, {"triangulate": make_method("triangulate")}, view_subsets(5, "all"), progress=False
    )
    row = results_rows(ev)[0]
    assert row["mpjpe"] < 5 and row["coverage"] == 100.0
    assert row["pcp_actor1"] == 80.0  # head and torso need ears the labels lack
    assert "pcp_actor3" in row


@pytest.mark.shared
@pytest.mark.parametrize("without_file", [False, True])
def test_campus_without_detections_falls_back_to_projection_and_says_so(
    fixtures, tmp_path, caplog, without_file
):
    """--2d auto never switches its 2D source silently: a WARNING, a header note saying
    why (the fixture's predictions cover none of its frames; or the file is missing), and
    results.csv's 2d_source column naming the source."""
    import shutil

    root = fixtures / "campus"
    if without_file:
        root = tmp_path / "campus"
        shutil.copytree(fixtures / "campus", root)
        (root / "pred_campus_maskrcnn_hrnet_coco.pkl").unlink()
    out = tmp_path / "out"
    caplog.set_level(logging.INFO)
    argv = ["--dataset", "campus", "--root", root, "--methods", "triangulate", "--views", "all"]
    assert _run(*argv, "--out", out) == 0
    text = (out / "results.md").read_text()
    why = "pred_campus_maskrcnn_hrnet_coco.pkl is missing" if without_file else "hold no keypoint"
    assert f"--2d auto: its {'detections file' if without_file else '2D detections'}" in text
    assert why in text and "ground truth projected through the noise model" in text
    assert ("hold no keypoint" in text) != without_file
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any("--2d auto" in w and why in w for w in warnings), warnings
    assert {r["2d_source"] for r in _rows(out / "results.csv")} == {"projection"}


@pytest.mark.shared
def test_user_keypoints_file_and_no_overlapping_frames(fixtures, tmp_path, capsys):
    """2D from a user file goes through association; frames not in the GT are an error."""
    evset = load_eval_set("campus", fixtures / "campus", two_d="projection", seed=3)
    part = evset.parts[0]
    kp = Keypoints2D(part.keypoints, part.scores, "coco17", part.rig.names, part.frames)
    save_keypoints(kp, tmp_path / "kp.npz")
    out = tmp_path / "out"
    assert (
        _run(
            "--dataset",
            "campus",
            "--root",
            fixtures / "campus",
            "--methods",
            FAST,
            "--views",
            "all",
            "--keypoints",
            tmp_path / "kp.npz",
            "--out",
            out,
        )
        == 0
    )
    text = (out / "results.md").read_text()
    assert "user file" in text and "associated by ray distance" in text
    assert float(_rows(out / "results.csv")[0]["coverage"]) > 50

    shifted = Keypoints2D(part.keypoints, part.scores, "coco17", part.rig.names, part.frames + 1000)
    save_keypoints(shifted, tmp_path / "late.npz")
    code = _run(
        "--dataset",
        "campus",
        "--root",
        fixtures / "campus",
        "--methods",
        FAST,
        "--keypoints",
        tmp_path / "late.npz",
    )
    assert code == 2
    err = capsys.readouterr().err
    assert "frames overlapping the ground truth" in err and "late.npz" in err


# --- perturbations, on the fixtures -----------------------------------------------------


@pytest.mark.shared
def test_view_counts_single_view_and_coverage(fixtures, tmp_path):
    """--views 1,2,3: RMPL lifts from one view; triangulation has no coverage there."""
    out = tmp_path / "v"
    assert (
        _run(
            "--dataset",
            "campus",
            "--root",
            fixtures / "campus",
            "--2d",
            "annotations",
            "--methods",
            "triangulate,rmpl",
            "--views",
            "1,2,3",
            "--out",
            out,
        )
        == 0
    )
    rows = {(r["views"], r["method"]): r for r in _rows(out / "results.csv")}
    one = "1 view (mean of 3)"
    assert float(rows[one, "triangulate"]["coverage"]) == 0.0
    assert rows[one, "triangulate"]["mpjpe"] == "nan"
    assert float(rows[one, "rmpl"]["coverage"]) == 100.0
    assert np.isfinite(float(rows[one, "rmpl"]["mpjpe"]))
    assert float(rows["3 views", "triangulate"]["coverage"]) == 100.0
    assert (out / "views.png").is_file()


@pytest.mark.shared
def test_dropout_sweep(fixtures, tmp_path):
    out = tmp_path / "d"
    assert (
        _run(
            "--dataset",
            "shelf",
            "--root",
            fixtures / "shelf",
            "--2d",
            "annotations",
            "--methods",
            FAST,
            "--views",
            "all",
            "--dropout",
            "0,0.5",
            "--out",
            out,
        )
        == 0
    )
    rows = _rows(out / "results.csv")
    assert sorted((r["method"], float(r["dropout"])) for r in rows) == [
        ("robust", 0.0),
        ("robust", 0.5),
        ("triangulate", 0.0),
        ("triangulate", 0.5),
    ]
    cov = {(r["method"], float(r["dropout"])): float(r["coverage"]) for r in rows}
    # Half of the keypoints removed in 5 views: some joints keep < 2 views.
    assert cov["triangulate", 0.5] < cov["triangulate", 0.0]
    assert "Sweep" in (out / "results.md").read_text()
    assert (out / "dropout.png").is_file()


@pytest.mark.shared
def test_dropout_is_identical_for_every_method(fixtures):
    """Two copies of one method see the same dropped keypoints: identical numbers."""
    evset = load_eval_set("shelf", fixtures / "shelf", two_d="annotations")
    methods = {"a": make_method("triangulate"), "b": make_method("triangulate")}
    ev = evaluate(
        evset, methods, view_subsets(5, "pairs"), EvalConfig(dropout=(0.3,)), progress=False
    )
    a, b = results_rows(ev)
    assert a["mpjpe"] == b["mpjpe"] and a["coverage"] == b["coverage"] < 100


@pytest.mark.shared
def test_calibration_noise(fixtures, tmp_path):
    out = tmp_path / "c"
    assert (
        _run(
            "--dataset",
            "shelf",
            "--root",
            fixtures / "shelf",
            "--2d",
            "annotations",
            "--methods",
            "triangulate",
            "--views",
            "all",
            "--calib-noise",
            "2,20",
            "--calib-reps",
            "2",
            "--out",
            out,
        )
        == 0
    )
    rows = _rows(out / "results.csv")
    assert [r["calib_noise"] for r in rows] == ["none", "2 deg, 20 mm"]
    clean, noisy = (float(r["mpjpe"]) for r in rows)
    assert noisy > clean + 5  # 2 deg at 4-5 m moves rays by ~15 cm
    text = (out / "results.md").read_text()
    assert "mean of 2 draws" in text and (out / "calib_noise.png").is_file()


# --- synthetic -----------------------------------------------------------------------


def _bank(tmp_path, n=40):
    rng = np.random.default_rng(0)
    base = np.array(
        [
            [0, -0.08, 1.62],
            [0.03, -0.07, 1.66],
            [-0.03, -0.07, 1.66],
            [0.07, 0, 1.64],
            [-0.07, 0, 1.64],
            [0.18, 0, 1.42],
            [-0.18, 0, 1.42],
            [0.2, 0, 1.15],
            [-0.2, 0, 1.15],
            [0.2, -0.05, 0.9],
            [-0.2, -0.05, 0.9],
            [0.1, 0, 0.95],
            [-0.1, 0, 0.95],
            [0.1, 0, 0.5],
            [-0.1, 0, 0.5],
            [0.1, 0, 0.08],
            [-0.1, 0, 0.08],
        ]
    )
    poses = (base + rng.normal(0, 0.03, (n, 17, 3))).astype(np.float32)
    bank = PoseSet(poses, np.array(["01", "03"] * (n // 2)), np.array(["c"] * n), np.arange(n))
    save_pose_set(tmp_path / "bank.npz", bank)
    return tmp_path / "bank.npz"


def test_sphere_cameras_geometry():
    K, R, t, wh = sphere_cameras(4.0, [-45.0, 45.0], radius=6.0, center=(0, 0, 1.0))
    centres = -np.einsum("vji,vj->vi", R, t)
    assert np.allclose(np.linalg.norm(centres - [0, 0, 1.0], axis=1), 6.0)
    assert np.allclose(centres[:, 2], 4.0)
    flat = centres[:, :2] / np.linalg.norm(centres[:, :2], axis=1, keepdims=True)
    assert np.isclose(np.degrees(np.arccos(flat[0] @ flat[1])), 90.0)
    # Aimed at the centre: it projects to the principal point.
    from rmpl.geometry.camera import project

    uv = project(np.array([0, 0, 1.0]), K, R, t)
    assert np.allclose(uv, K[:, :2, 2])
    with pytest.raises(ValueError, match="out of reach"):
        sphere_cameras(8.0, [0.0], radius=6.0)


def test_synthetic_sphere_sweep(tmp_path):
    out = tmp_path / "s"
    assert (
        _run(
            "--dataset",
            "synthetic",
            "--root",
            _bank(tmp_path),
            "--cameras",
            "sphere",
            "--heights",
            "2.2",
            "--angles",
            "10,90",
            "--samples",
            "40",
            "--methods",
            "triangulate",
            "--out",
            out,
        )
        == 0
    )
    rows = {float(r["angle"]): float(r["mpjpe"]) for r in _rows(out / "results.csv")}
    # A 10 degree baseline triangulates depth far worse than a 90 degree one.
    assert rows[10.0] > 1.5 * rows[90.0]
    assert (out / "sphere.png").is_file() and "MPJPE (mm) by angle" in (
        out / "results.md"
    ).read_text()


def test_synthetic_dropout_and_calibration(tmp_path):
    out = tmp_path / "d"
    assert (
        _run(
            "--dataset",
            "synthetic",
            "--root",
            _bank(tmp_path),
            "--views",
            "4",
            "--samples",
            "30",
            "--methods",
            "triangulate",
            "--dropout",
            "0,0.4",
            "--calib-noise",
            "2,20",
            "--calib-reps",
            "1",
            "--out",
            out,
        )
        == 0
    )
    rows = _rows(out / "results.csv")
    got = {(float(r["dropout"]), r["calib_noise"]): r for r in rows}
    assert set(got) == {(0.0, "none"), (0.4, "none"), (0.0, "2 deg, 20 mm"), (0.4, "2 deg, 20 mm")}
    assert float(got[0.4, "none"]["coverage"]) < float(got[0.0, "none"]["coverage"])
    assert float(got[0.0, "2 deg, 20 mm"]["mpjpe"]) > float(got[0.0, "none"]["mpjpe"])
    assert (out / "dropout.png").is_file() and (out / "per_joint.csv").is_file()


def test_pose_metrics_units_and_missing():
    gt = np.zeros((2, 17, 3))
    pred = gt + [0.0, 0.0, 0.1]  # 100 mm everywhere
    pred[0, 0] = np.nan  # one joint missing
    m = pose_metrics(pred, gt, range(17), 0.150)
    assert np.isclose(m["mpjpe"], 100) and np.isclose(m["kpstar"], 100)
    assert np.isclose(m["coverage"], 100 * 33 / 34) and np.isclose(m["pck"], 100 * 33 / 34)
    gt2 = np.random.default_rng(0).normal(size=(2, 17, 3))
    assert pose_metrics(gt2 * 2 + 1, gt2, range(17))["pa_mpjpe"] < 1e-6


# --- bad input ------------------------------------------------------------------------


def test_unknown_dataset_and_method(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        _run("--dataset", "mpii", "--root", tmp_path)
    assert e.value.code == 2 and "mpii" in capsys.readouterr().err
    assert _run("--dataset", "synthetic", "--root", _bank(tmp_path), "--methods", "magic") == 2
    err = capsys.readouterr().err
    assert "'--methods'" in err and "got magic" in err


@pytest.mark.parametrize("dataset", ["shelf", "campus", "panoptic", "h36m"])
def test_missing_folder(tmp_path, capsys, dataset):
    assert _run("--dataset", dataset, "--root", tmp_path / "nope", "--methods", FAST) == 2
    err = capsys.readouterr().err
    assert "nope" in err and "Traceback" not in err


@pytest.mark.parametrize("dataset", ["shelf", "campus", "panoptic", "h36m"])
def test_wrong_layout(tmp_path, capsys, dataset):
    (tmp_path / "something.txt").write_text("not a dataset")
    assert _run("--dataset", dataset, "--root", tmp_path, "--methods", FAST) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path) in err[0], err


@pytest.mark.shared
def test_view_count_larger_than_the_rig(fixtures, capsys):
    assert (
        _run(
            "--dataset",
            "campus",
            "--root",
            fixtures / "campus",
            "--methods",
            FAST,
            "--views",
            "1,4",
        )
        == 2
    )
    assert "4 view(s) requested but the dataset's rig has 3 cameras" in capsys.readouterr().err


def test_bad_perturbation_options(tmp_path, capsys):
    bank = _bank(tmp_path)
    for opts, text in (
        (["--dropout", "0,1.5"], "--dropout"),
        (["--calib-noise", "2"], "DEG,MM"),
        (["--dropout", "a"], "comma-separated numbers"),
        (["--cameras", "sphere", "--angles", "0,400"], "angles in (0, 180]"),
        (["--cameras", "dome"], "'random' or 'sphere'"),
    ):
        assert (
            _run(
                "--dataset",
                "synthetic",
                "--root",
                bank,
                "--methods",
                "triangulate",
                "--samples",
                "5",
                *opts,
            )
            == 2
        ), opts
        assert text in capsys.readouterr().err, opts


@pytest.mark.shared
def test_keypoint_file_missing(tmp_path, capsys, shared_data):
    root = shared_data / "fixtures" / "campus"
    if not root.is_dir():
        pytest.skip(f"{root} not found")
    assert (
        _run(
            "--dataset",
            "campus",
            "--root",
            root,
            "--methods",
            FAST,
            "--keypoints",
            tmp_path / "none.json",
        )
        == 2
    )
    assert "none.json" in capsys.readouterr().err


@pytest.mark.shared
def test_annotations_requested_where_there_are_none(shared_data, capsys):
    root = shared_data / "fixtures" / "panoptic_body3d"
    if not root.is_dir():
        pytest.skip(f"{root} not found")
    with pytest.raises(InputError, match="annotations"):
        load_eval_set("panoptic", root, two_d="annotations")


# --- finished results (--poses) -------------------------------------------------------


@pytest.mark.shared
def test_score_finished_results(fixtures, tmp_path, capsys):
    """Results written by another run are matched by frame number and person; a shifted
    person scores exactly its shift, a ghost person is ignored, a missing one is missing."""
    from rmpl.io.poses import Poses3D, save_poses

    root = fixtures / "shelf"
    evset = load_eval_set("shelf", root, two_d="annotations")
    part = evset.parts[0]
    gt = gt_coco(part)  # (T, P, 17, 3)
    present = np.isfinite(gt).all(-1).any(-1)
    t0, p0 = np.argwhere(present)[0]
    shifted = gt.copy()
    shifted[t0, p0] += [0.1, 0.0, 0.0]
    ghost = np.full((len(gt), 1, 17, 3), np.nan)
    ghost[:, 0] = gt[t0, p0] + [20.0, 0.0, 0.0]  # far outside the 0.5 m gate
    people = np.concatenate([shifted[:, ::-1], ghost], axis=1)  # order must not matter
    res = Poses3D(points=people, frames=part.frames, fps=25.0)
    ev = evaluate_poses(evset, {"exact": Poses3D(points=gt, frames=part.frames), "moved": res})
    rows = {r["method"]: r for r in results_rows(ev)}
    n = int(np.isfinite(gt[present][..., ev.joints, :]).all(-1).sum())
    moved_joints = int(np.isfinite(gt[t0, p0, ev.joints]).all(-1).sum())
    # (PCP is not 100: the head part uses a neck and head top derived from COCO-17)
    assert rows["exact"]["mpjpe"] < 1e-6 and rows["exact"]["pcp_mean"] >= rows["moved"]["pcp_mean"]
    assert np.isclose(rows["moved"]["mpjpe"], 100 * moved_joints / n)
    assert np.isclose(rows["exact"]["coverage"], 100)

    # One frame missing from the result: its people count as not estimated.
    short = Poses3D(points=gt[1:], frames=part.frames[1:])
    cov = {r["method"]: r["coverage"] for r in results_rows(evaluate_poses(evset, {"s": short}))}
    assert cov["s"] < 100

    # Through the command line, from a file.
    shelf = ["--dataset", "shelf", "--root", root, "--2d", "annotations"]
    save_poses(res, tmp_path / "run" / "poses.npz")
    out = tmp_path / "eval"
    assert _run(*shelf, "--poses", tmp_path / "run" / "poses.npz", "--out", out) == 0
    assert [r["method"] for r in _rows(out / "results.csv")] == ["run"]
    assert [r["2d_source"] for r in _rows(out / "results.csv")] == ["none"]  # no 2D used
    assert "finished 3D results" in (out / "results.md").read_text()

    # Frames that do not overlap, and options that cannot apply, are one-line errors.
    save_poses(Poses3D(points=gt, frames=part.frames + 10_000), tmp_path / "far.npz")
    capsys.readouterr()
    assert _run(*shelf, "--poses", tmp_path / "far.npz") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "frames" in err[0], err
    assert _run(*shelf, "--poses", tmp_path / "far.npz", "--views", "pairs") == 2
    assert "--views" in capsys.readouterr().err


# --- one view: root error, height ratio, rmpl+floor -------------------------------------


def _standing(height_scale=1.0):
    """A hand-made upright COCO-17 pose: shins 0.43, thighs 0.40, trunk 0.50 m (proxy =
    1.33 / 0.779 = 1.707 m), hips at x = -+0.1."""
    x = np.zeros((17, 3))
    x[:, 2] = 1.6  # head joints
    x[[15, 16], 2], x[[13, 14], 2], x[[11, 12], 2], x[[5, 6], 2] = 0.07, 0.5, 0.9, 1.4
    x[[5, 7, 9, 11, 13, 15], 0], x[[6, 8, 10, 12, 14, 16], 0] = 0.1, -0.1
    return x * height_scale


def test_root_metrics_by_hand():
    from rmpl.evaluate.scoring import root_metrics

    gt = np.stack([_standing(), _standing() + [2.0, 1.0, 0.0]])
    pred = np.stack([_standing(1.1) + [0.0, 0.3, 0.0], _standing(0.9) + [2.0, 1.0, 0.4]])
    # pelvis (the hips' midpoint at z = 0.9 x scale): pose 0 moves by (0, 0.3, 0.09),
    # pose 1 by (0, 0, 0.4 - 0.09)
    m = root_metrics(pred, gt)
    assert m["root"] == pytest.approx(1000 * (np.hypot(0.3, 0.09) + 0.31) / 2)
    assert m["height_ratio"] == pytest.approx(1.0)  # the median of 1.1 and 0.9
    pred[1, 11] = np.nan  # a hip missing: pose 1 has no pelvis and no trunk length
    m = root_metrics(pred, gt)
    assert m["root"] == pytest.approx(1000 * np.hypot(0.3, 0.09))
    assert m["height_ratio"] == pytest.approx(1.1)  # pose 0 alone
    pred[1, 11] = pred[1, 12] * [-1, 1, 1] + [4.0, 0, 0]  # restored (x mirrored about 2 m)
    pred[1, 13] = np.nan  # a knee missing: the other leg still measures shin and thigh
    assert root_metrics(pred, gt)["height_ratio"] == pytest.approx(1.0)
    assert np.isnan(root_metrics(np.full((1, 17, 3), np.nan), gt[:1])["root"])


@pytest.mark.shared
def test_one_view_columns_and_rmpl_floor(fixtures, tmp_path):
    """--views 1 adds the root error and height ratio; rmpl+floor engages only with one
    view and is plain rmpl with more."""
    out = tmp_path / "v"
    argv = ["--dataset", "campus", "--root", fixtures / "campus", "--2d", "annotations",
            "--methods", "rmpl,rmpl+floor:floor+size", "--views", "1,3", "--out", out,
            "--no-plots"]  # fmt: skip
    assert _run(*argv) == 0
    rows = {(r["views"], r["method"]): r for r in _rows(out / "results.csv")}
    one = "1 view (mean of 3)"
    for m in ("rmpl", "rmpl+floor:floor+size"):
        assert float(rows[one, m]["root"]) > 0 and 0.5 < float(rows[one, m]["height_ratio"]) < 2
    assert rows["3 views", "rmpl"]["mpjpe"] == rows["3 views", "rmpl+floor:floor+size"]["mpjpe"]
    text = (out / "results.md").read_text()
    assert "root error (mm)" in text and "height ratio" in text
    assert "rmpl+floor (one view" in text  # the header says where the floor came from


def test_floor_option_needs_a_floor_method_and_a_plane(tmp_path, capsys):
    bank = _bank(tmp_path)
    assert _run("--dataset", "synthetic", "--root", bank, "--methods", "triangulate",
                "--floor", "z=0", "--views", "1", "--samples", "2") == 2  # fmt: skip
    assert "rmpl+floor" in capsys.readouterr().err
    assert _run("--dataset", "synthetic", "--root", bank, "--methods", "rmpl+floor",
                "--floor", "estimate", "--views", "1", "--samples", "2") == 2  # fmt: skip
    assert "'estimate' needs" in capsys.readouterr().err
    assert _run("--dataset", "synthetic", "--root", bank, "--methods", "rmpl+floor",
                "--floor", "0,0,0,1", "--views", "1", "--samples", "2") == 2  # fmt: skip
    assert "plane" in capsys.readouterr().err
    assert _run("--dataset", "synthetic", "--root", bank, "--methods", "rmpl+floor:hop",
                "--views", "1", "--samples", "2") == 2  # fmt: skip
    assert "floor, size, time" in capsys.readouterr().err


def test_rmpl_floor_on_synthetic_scenes_uses_the_given_floor(tmp_path):
    """The synthetic generator stands the lowest joint on z = 0: with that floor (ankles
    rest at z = 0, so the floor is 0.07 below) the depth is better than the lifter's."""
    bank = _bank(tmp_path, n=60)
    out = tmp_path / "s"
    assert _run("--dataset", "synthetic", "--root", bank, "--methods", "rmpl,rmpl+floor:floor",
                "--floor", "z=-0.07", "--views", "1", "--samples", "40", "--out", out,
                "--no-plots") == 0  # fmt: skip
    rows = {r["method"]: r for r in _rows(out / "results.csv")}
    assert float(rows["rmpl+floor:floor"]["mpjpe"]) < float(rows["rmpl"]["mpjpe"])
