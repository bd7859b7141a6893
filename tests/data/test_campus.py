"""Tests of rmpl.data.campus: a synthetic VoxelPose-layout folder, then the real fixtures."""

from __future__ import annotations

import collections
import json
import pickle

import numpy as np
import pytest
import scipy.io

from rmpl.data.base import MultiViewDataset, coco17_by_name
from rmpl.data.campus import (
    EVAL_FRAMES,
    IMAGE_SIZES,
    load_actors_gt,
    load_campus_layout,
    load_hrnet_predictions,
)
from rmpl.errors import InputError
from rmpl.geometry.camera import look_at
from rmpl.skeleton import SHELF14, SHELF_LIMB_JOINTS


def _cells(rows: list) -> np.ndarray:
    """A MATLAB cell array (len(rows), 1) of the given matrices."""
    out = np.empty((len(rows), 1), dtype=object)
    for i, r in enumerate(rows):
        out[i, 0] = r
    return out


def _write_folder(root, rng, num_views=3, name="campus"):
    """Cameras, a 4-frame actorsGT.mat (actor 1 absent in frame 2) and HRNet predictions."""
    cams = {}
    for v in range(num_views):
        a = 2 * np.pi * v / num_views
        R, t = look_at(np.array([5 * np.cos(a), 5 * np.sin(a), 2.5]), np.array([0, 0, 1.0]))
        cams[str(v)] = {
            "R": R.tolist(),
            "T": (-R.T @ t * 1000)[:, None].tolist(),
            "fx": 400.0,
            "fy": 410.0,
            "cx": 180.0,
            "cy": 144.0,
            "k": [[0.0], [0.0], [0.0]],
            "p": [[0.0], [0.0]],
        }
    (root / f"calibration_{name}.json").write_text(json.dumps(cams))
    T, P = 4, 2
    gt = rng.uniform(-0.5, 0.5, (T, P, 14, 3)) + np.array([0, 0, 1.0])
    actor3d = np.empty((1, P), dtype=object)
    actor2d = np.empty((1, P), dtype=object)
    for p in range(P):
        present = [not (p == 1 and t == 2) for t in range(T)]
        actor3d[0, p] = _cells(
            [gt[t, p] if ok else np.zeros((1, 0)) for t, ok in enumerate(present)]
        )
        views = []
        for ok in present:
            c = np.empty((1, num_views), dtype=object)
            for v in range(num_views):
                c[0, v] = rng.uniform(0, 300, (14, 2)) if ok else np.zeros((1, 0))
            views.append(c)
        actor2d[0, p] = _cells(views)
    gt[2, 1] = np.nan
    scipy.io.savemat(root / "actorsGT.mat", {"actor3D": actor3d, "actor2D": actor2d})
    return gt


def _pred(points_xy, score=0.9):
    return {"pred": np.column_stack([points_xy, np.full(len(points_xy), score)])}


@pytest.fixture
def folder(tmp_path):
    rng = np.random.default_rng(1)
    gt = _write_folder(tmp_path, rng)
    data = load_campus_layout(tmp_path, "campus")  # without predictions yet
    # Predictions: frame 1 view 2 holds two people; frame 3 view 0 one; the rest nobody.
    coco = data.rig.project(gt[..., coco17_by_name(SHELF14).clip(0), :])  # (T, P, V, 17, 2)
    coco = coco.transpose(0, 2, 1, 3, 4)  # (T, V, P, 17, 2)
    preds = collections.defaultdict(list)
    preds["2_1"] = [_pred(coco[1, 2, 1]), _pred(coco[1, 2, 0] + 3.0)]
    preds["0_3"] = [_pred(coco[3, 0, 0], score=0.0)]  # zero score: missing
    preds["1_0"] = []
    (tmp_path / "pred_campus_maskrcnn_hrnet_coco.pkl").write_bytes(pickle.dumps(preds))
    return tmp_path, gt, coco


def test_synthetic_folder_shapes_and_units(folder):
    root, gt, coco = folder
    data = load_campus_layout(root, "campus")
    assert isinstance(data, MultiViewDataset) and data.name == "campus"
    assert data.rig.names == ["0", "1", "2"] and all(
        c.size == IMAGE_SIZES["campus"] for c in data.rig
    )
    assert data.frames.tolist() == [0, 1, 2, 3] and data.gt_skeleton == "shelf14"
    np.testing.assert_allclose(data.gt, gt, atol=1e-9)  # metres in, metres out
    assert np.isnan(data.gt[2, 1]).all() and not np.isnan(data.gt[2, 0]).any()
    assert data.keypoints.shape == (4, 3, 2, 17, 2) and data.scores.shape == (4, 3, 2, 17)
    np.testing.assert_allclose(data.keypoints[1, 2, 0], coco[1, 2, 1], atol=1e-9)
    np.testing.assert_allclose(data.keypoints[1, 2, 1], coco[1, 2, 0] + 3.0, atol=1e-9)
    assert np.all(data.scores[1, 2] == 0.9)
    others = np.ones((4, 3), bool)
    others[1, 2] = False
    assert np.isnan(data.keypoints[others]).all() and np.all(data.scores[others] == 0)


def test_frames_subset_and_camera_centres_in_mm(folder):
    root, gt, _ = folder
    data = load_campus_layout(root, "campus", frames=[3, 1])
    assert data.frames.tolist() == [3, 1]
    np.testing.assert_allclose(data.gt, gt[[3, 1]], atol=1e-9)
    assert data.keypoints.shape[:2] == (2, 3) and data.scores[1, 2, 0].max() == 0.9
    # The camera centres were written 5 m from the origin in millimetres.
    radius = np.linalg.norm(data.rig.centers[:, :2], axis=1)
    np.testing.assert_allclose(radius, 5.0, atol=1e-9)
    with pytest.raises(InputError, match="frames"):
        load_campus_layout(root, "campus", frames=[4])


def test_actors_gt_2d_and_uint_cells(folder):
    root, gt, _ = folder
    gt3d, gt2d = load_actors_gt(root / "actorsGT.mat")
    assert gt3d.shape == (4, 2, 14, 3) and gt2d.shape == (4, 2, 3, 14, 2)
    assert np.isnan(gt2d[2, 1]).all() and np.isfinite(gt2d[2, 0]).all()
    assert gt2d.dtype == float


def test_missing_predictions_mean_no_keypoints(tmp_path):
    _write_folder(tmp_path, np.random.default_rng(2), num_views=5, name="shelf")
    data = load_campus_layout(tmp_path, "shelf")
    assert data.keypoints is None and data.scores is None
    assert data.rig[0].size == IMAGE_SIZES["shelf"]


def test_bad_inputs_name_file_and_field(folder):
    root, _, _ = folder
    with pytest.raises(InputError, match="dataset"):
        load_campus_layout(root, "panoptic")
    with pytest.raises(InputError, match="calibration_shelf.json"):
        load_campus_layout(root, "shelf")
    pred = root / "pred_campus_maskrcnn_hrnet_coco.pkl"
    pred.write_bytes(pickle.dumps({"0_1": [{"pred": np.zeros((15, 3))}]}))
    with pytest.raises(InputError, match=r"0_1\[0\]\.pred.*\(17, 3\)"):
        load_campus_layout(root, "campus")
    pred.write_bytes(pickle.dumps({"7_1": [_pred(np.ones((17, 2)))]}))
    with pytest.raises(InputError, match="'7_1'.*cameras"):
        load_campus_layout(root, "campus")
    pred.write_bytes(pickle.dumps({"frame1": []}))
    with pytest.raises(InputError, match="<camera>_<frame>"):
        load_campus_layout(root, "campus")
    pred.write_bytes(pickle.dumps({"0_1": [collections.OrderedDict()]}))  # a refused global
    with pytest.raises(InputError, match="plain dicts"):
        load_campus_layout(root, "campus")
    (root / "actorsGT.mat").write_text("not a mat file")
    with pytest.raises(InputError, match=r"actorsGT\.mat.*MATLAB"):
        load_campus_layout(root, "campus")


def test_bad_actor_cell_shape(tmp_path):
    _write_folder(tmp_path, np.random.default_rng(3))
    actor3d = np.empty((1, 1), dtype=object)
    actor3d[0, 0] = _cells([np.zeros((15, 3))])
    scipy.io.savemat(tmp_path / "actorsGT.mat", {"actor3D": actor3d})
    with pytest.raises(InputError, match=r"actor3D\{1\}\{1\}.*14 x 3"):
        load_actors_gt(tmp_path / "actorsGT.mat")


def test_eval_frames():
    assert (EVAL_FRAMES["shelf"][0], EVAL_FRAMES["shelf"][-1]) == (300, 600)
    assert len(EVAL_FRAMES["campus"]) == 121 + 101


# --- The real fixtures (skipped without ../shared/data) ---------------------------------


@pytest.fixture(params=["shelf", "campus"])
def real(request, shared_data):
    root = shared_data / "fixtures" / request.param
    if not root.is_dir():
        pytest.skip(f"{root} not found")
    return root, request.param


@pytest.mark.shared
def test_fixture_shapes_and_metres(real):
    root, name = real
    data = load_campus_layout(root, name)
    P, V = {"shelf": (4, 5), "campus": (3, 3)}[name]
    assert data.gt.shape == (3, P, 14, 3) and len(data.rig) == V
    present = ~np.isnan(data.gt).any(axis=(2, 3))
    assert present.any(axis=1).all()
    # Metres: a standing person's head top is 1.5-2.1 m above the ankles, the floor at z ~ 0.
    X = data.gt[present]  # (people, 14, 3)
    height = X[:, SHELF14.index("head_top"), 2] - X[:, :6:5, 2].mean(1)
    assert np.all((height > 1.4) & (height < 2.1))
    assert np.all(np.abs(X[:, [0, 5], 2]) < 0.3)


@pytest.mark.shared
def test_fixture_gt_reprojects_onto_the_2d_annotation(real):
    """actorsGT's 3D, projected with the VoxelPose calibration, lands on its own 2D labels.

    Shelf's 2D labels agree to < 0.5 px (measured max 0.04 px). Campus's are whole pixels
    and not exact projections: median < 1.5 px, all < 4 px (measured 0.5 and 2.7 px).
    """
    root, name = real
    data = load_campus_layout(root, name)
    _, gt2d = load_actors_gt(root / "actorsGT.mat")
    proj = data.rig.project(data.gt.reshape(3, -1, 3)).reshape(3, len(data.rig), -1, 14, 2)
    err = np.linalg.norm(proj - gt2d.transpose(0, 2, 1, 3, 4), axis=-1)  # (T, V, P, 14)
    have = np.isfinite(err)
    assert have.sum() >= 3 * len(data.rig) * 14
    assert np.median(err[have]) < 1.5
    assert np.max(err[have]) < {"shelf": 0.5, "campus": 4.0}[name]


@pytest.mark.shared
def test_fixture_hrnet_predictions(real):
    """The HRNet 2D: COCO-17 inside the image with scores in (0, 1] where present.

    The fixture's predictions are not of the same instants as its ground truth (the
    nearest predicted person is 40-330 px from the projected ground truth), so they are
    checked for form, not against the ground truth; the synthetic test above checks the
    key -> (view, frame) alignment.
    """
    root, name = real
    data = load_campus_layout(root, name)
    assert data.keypoints is not None and data.keypoints.shape[:2] == (3, len(data.rig))
    ok = data.scores > 0
    if name == "campus":  # the fixture's Campus predictions are empty lists
        assert data.keypoints.shape[2] == 0
        return
    assert ok.mean() > 0.5 and np.all(data.scores[ok] <= 1)
    xy = data.keypoints[ok]
    assert np.all((xy >= 0) & (xy <= np.array(IMAGE_SIZES[name]) - 1))
    # The people are person-sized: hips below shoulders in the image (y down).
    people = ok[..., [5, 6, 11, 12]].all(-1)
    kp = data.keypoints[people]
    assert np.mean(kp[:, 11:13, 1].mean(1) > kp[:, 5:7, 1].mean(1)) > 0.9


def test_load_hrnet_predictions_keeps_only_requested_frames(folder):
    root, _, coco = folder
    data = load_campus_layout(root, "campus", frames=[0])
    kp, sc = load_hrnet_predictions(
        root / "pred_campus_maskrcnn_hrnet_coco.pkl", data.rig, np.array([1])
    )
    assert kp.shape == (1, 3, 2, 17, 2)
    np.testing.assert_allclose(kp[0, 2, 0], coco[1, 2, 1], atol=1e-9)
    # The limb joints, and only those, have a Shelf counterpart.
    assert (coco17_by_name(SHELF14) >= 0).sum() == len(SHELF_LIMB_JOINTS)
