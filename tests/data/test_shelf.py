"""Tests of rmpl.data.shelf: a synthetic folder written here, then the real shelf_dev."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.data.shelf import load_shelf
from rmpl.errors import InputError
from rmpl.geometry.camera import look_at
from rmpl.geometry.triangulate import triangulate
from rmpl.pipeline.association import (
    BODY25_LIMBS,
    associate,
    group_people,
    match_poses,
)
from rmpl.skeleton import BODY25, SHELF14, SHELF_LIMB_JOINTS, convert

W, H = 1032, 776


def _write_calibration(path, num_views=5):
    cams = {}
    for v in range(num_views):
        a = 2 * np.pi * v / num_views
        R, t = look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 2.0]), np.array([0, 0, 1.0]))
        K = [1000.0, 0, W / 2, 0, 1000.0, H / 2, 0, 0, 1]
        cams[str(v)] = {"K": K, "RT": np.column_stack([R, t]).ravel().tolist(), "imgSize": [W, H]}
    path.write_text(json.dumps(cams, indent=1))


def _candidates(rng, frame: int):
    """Normalised candidates per BODY_25 joint (0, 1 or 2 each) and affinities per limb."""
    points = [rng.uniform(0, 1, (3, (j + frame) % 3)) for j in range(25)]  # rows x, y, score
    affinities = [
        rng.uniform(0, 1, (points[a].shape[1], points[b].shape[1])) for a, b in BODY25_LIMBS
    ]
    return points, affinities


def _detection_text(frames) -> str:
    out = [f"4\t{len(frames)}"]
    for points, affinities in frames:
        for p in points:
            out.append(str(p.shape[1]))
            out.extend(" ".join(f"{x:.6f}" for x in row) for row in p)
        out.extend(" ".join(f"{x:.6f}" for x in A.ravel()) for A in affinities)
    return "\n".join(out) + "\n"


@pytest.fixture
def shelf_folder(tmp_path):
    """A 2-frame Shelf folder: frame 0 has actors 0 and 2, frame 1 actor 3 only."""
    rng = np.random.default_rng(0)
    _write_calibration(tmp_path / "calibration.json")
    gt = rng.uniform(-1, 2, (2, 4, 15, 3))

    def person(t, i):  # id, then the 4 x 15 matrix: rows x, y, z, 1
        return f"{i} " + " ".join(f"{x:.6f}" for x in np.vstack([gt[t, i].T, np.ones(15)]).ravel())

    lines = ["15\t2", "2", person(0, 0), person(0, 2), "1", person(1, 3)]
    (tmp_path / "gt.txt").write_text("\n".join(lines) + "\n")
    (tmp_path / "first_frame.txt").write_text("300\n")
    (tmp_path / "detection").mkdir()
    dets = [[_candidates(rng, f) for f in range(2)] for _ in range(5)]
    for v in range(5):
        (tmp_path / "detection" / f"{v}.txt").write_text(_detection_text(dets[v]))
    return tmp_path, gt, dets


def test_load_shelf_synthetic_folder(shelf_folder):
    root, gt, dets = shelf_folder
    data = load_shelf(root)
    assert len(data) == 2 and data.frames.tolist() == [300, 301]
    assert data.gt.shape == (2, 4, 15, 3)
    np.testing.assert_allclose(data.gt[0, [0, 2]], gt[0, [0, 2]], atol=1e-6)
    np.testing.assert_allclose(data.gt[1, 3], gt[1, 3], atol=1e-6)
    assert np.isnan(data.gt[0, [1, 3]]).all() and np.isnan(data.gt[1, :3]).all()
    assert len(data.rig) == 5 and data.rig.names == ["0", "1", "2", "3", "4"]
    cands = data.detections[1][3]  # frame 1, view 3
    points, affinities = dets[3][1]
    for j in range(25):
        expected = np.column_stack([points[j][0] * (W - 1), points[j][1] * (H - 1), points[j][2]])
        np.testing.assert_allclose(cands.points[j], expected, atol=1e-3)
    for A, B in zip(cands.affinities, affinities, strict=True):
        np.testing.assert_allclose(A, B, atol=1e-6)


def test_load_shelf_reports_truncated_detections(shelf_folder):
    root, _, _ = shelf_folder
    path = root / "detection" / "2.txt"
    path.write_text(" ".join(path.read_text().split()[:-3]))
    with pytest.raises(InputError, match=r"2\.txt.*frame 1, limb"):
        load_shelf(root)


def test_load_shelf_reports_bad_headers_and_counts(shelf_folder):
    root, _, _ = shelf_folder
    det = root / "detection" / "0.txt"
    det.write_text("5" + det.read_text()[1:])
    with pytest.raises(InputError, match=r"0\.txt.*header.*expected first token 4"):
        load_shelf(root)
    det.write_text("4" + det.read_text()[1:])
    gt = root / "gt.txt"
    gt.write_text(gt.read_text().replace("\n1\n3 ", "\n1\n7 "))
    with pytest.raises(InputError, match=r"gt\.txt.*actor id"):
        load_shelf(root)
    with pytest.raises(InputError, match="Shelf folder"):
        load_shelf(root / "absent")


def test_load_shelf_reports_frame_count_mismatch(shelf_folder):
    root, _, _ = shelf_folder
    gt = root / "gt.txt"
    lines = gt.read_text().splitlines()
    gt.write_text("\n".join(["15 1", *lines[1:4]]) + "\n")
    with pytest.raises(InputError, match=r"detection/0\.txt.*1 frames, as in gt\.txt"):
        load_shelf(root)


# --- The real shelf_dev (skipped without ../shared/data) --------------------------------


@pytest.fixture
def shelf(shared_data):
    root = shared_data / "shelf_dev"
    if not root.is_dir():
        pytest.skip(f"{root} not found")
    return load_shelf(root)


@pytest.mark.shared
def test_shelf_dev_shapes_and_units(shelf):
    T = len(shelf)
    assert T == 150 and shelf.frames[0] == 300 and np.all(np.diff(shelf.frames) == 1)
    assert shelf.gt.shape == (T, 4, 15, 3) and len(shelf.detections) == T
    assert all(len(frame) == 5 for frame in shelf.detections)
    present = np.isfinite(shelf.gt).all((-1, -2))  # (T, 4)
    assert present[:, 0].all() and present.sum(1).min() >= 1
    g = shelf.gt[present]  # (N, 15, 3), metres, z up
    head_height = g[:, SHELF14.index("head_top"), 2] - g[:, SHELF14.index("right_ankle"), 2]
    assert 1.4 < np.median(head_height) < 2.1
    np.testing.assert_allclose(g[:, 14], g[:, [2, 3]].mean(1), atol=1e-4)  # mid-hip
    xy = np.concatenate([p[:, :2] for frame in shelf.detections for c in frame for p in c.points])
    assert xy.min() >= 0 and (xy <= [W - 1, H - 1]).all() and xy[:, 0].max() > W / 2


@pytest.mark.shared
def test_shelf_gt_reprojects_onto_detections(shelf):
    """The nearest candidate of each Shelf limb joint is close to the projected GT joint.

    Measured on shelf_dev: median 13 px, 90% within 50 px (GT and OpenPose joint
    definitions differ and occluded joints have no nearby candidate).
    """
    body25 = [BODY25.index(SHELF14.joints[j]) for j in SHELF_LIMB_JOINTS]
    errors = []
    for t in range(0, len(shelf), 5):
        for a in np.flatnonzero(np.isfinite(shelf.gt[t]).all((-1, -2))):
            proj = shelf.rig.project(shelf.gt[t, a, list(SHELF_LIMB_JOINTS)])  # (V, 12, 2)
            for v, cands in enumerate(shelf.detections[t]):
                for k, j in enumerate(body25):
                    pts = cands.points[j][:, :2]
                    near = np.linalg.norm(pts - proj[v, k], axis=1).min() if len(pts) else np.inf
                    errors.append(near)
    errors = np.array(errors)
    assert np.median(errors) < 20
    assert np.mean(errors < 50) > 0.85


@pytest.mark.shared
def test_shelf_gt_ids_are_the_actors_gt_columns(shared_data):
    """gt.txt id i is column i of Shelf's actorsGT.mat (so ids 0..2 are actors 1-3)."""
    from scipy.io import loadmat

    mat = shared_data / "fixtures" / "shelf" / "actorsGT.mat"
    root = shared_data / "shelf_dev"
    if not mat.is_file() or not root.is_dir():
        pytest.skip("Shelf fixture or shelf_dev not found")
    gt = load_shelf(root).gt[:, :, :14]
    actors = loadmat(mat)["actor3D"][0]
    exact = set()
    for col, frames in enumerate(actors):
        for pose in frames[:, 0]:
            if pose.size == 0:
                continue
            dist = np.nan_to_num(np.abs(gt - pose).max((-1, -2)), nan=np.inf).min(0)  # per id
            assert np.argmin(dist) == col and dist[col] < 0.1
            if dist[col] < 1e-4:  # the same pose, to the printed precision
                exact.add(col)
    assert exact == {0, 2}  # the two actors annotated in frames 300-449


@pytest.mark.shared
def test_shelf_pipeline_recovers_the_actors(shelf):
    """Grouping + association + triangulation finds every annotated actor in most frames."""
    frames = range(0, len(shelf), 3)
    found, present, errors = 0, 0, []
    for t in frames:
        people = [group_people(c) for c in shelf.detections[t]]
        result = associate([p[0] for p in people], [p[1] for p in people], shelf.rig)
        points = triangulate(result.keypoints, result.scores, shelf.rig).points
        pred = convert(points, "coco17", "shelf14")
        gt = shelf.gt[t, :, :14]
        match = match_poses(pred, gt, 0.5, SHELF_LIMB_JOINTS)
        for a in np.flatnonzero(np.isfinite(gt).all((-1, -2))):
            present += 1
            if match[a] >= 0:
                found += 1
                e = np.linalg.norm(pred[match[a]] - gt[a], axis=-1)[list(SHELF_LIMB_JOINTS)]
                errors.append(np.nanmean(e))
    assert present > 50
    assert found / present > 0.95
    assert np.mean(errors) < 0.08  # metres, limb joints; measured about 0.05
