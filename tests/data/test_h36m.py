"""Tests of rmpl.data.h36m: a synthetic MMPose-layout folder, then the real fixture."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from rmpl.data.base import coco17_by_name
from rmpl.data.h36m import h36m_subjects, load_h36m
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, look_at
from rmpl.skeleton import COCO17, H36M17

CAM_IDS = ("54138969", "55011271", "58860488", "60457274")
ANN, DET = "h36m_test.npz", "h36m_det.npy"


def _cameras(subject_shift: float) -> list[Camera]:
    cams = []
    for i, cid in enumerate(CAM_IDS):
        a = np.pi / 4 + np.pi / 2 * i
        eye = np.array([4 * np.cos(a) + subject_shift, 4 * np.sin(a), 1.5])
        R, t = look_at(eye, np.array([0, 0, 1.0]))
        K = [[1145.0, 0, 512.0], [0, 1144.0, 515.0], [0, 0, 1]]
        cams.append(Camera(K, R, t, [-0.2, 0.24, -1e-3, -1e-3, -3e-3], (1000, 1002), cid))
    return cams


def _pkl_entry(c: Camera) -> dict:
    """mmpose's cameras.pkl entry: R camera->world, T the centre in metres, columns."""
    return {
        "R": c.R.T,
        "T": c.center[:, None],
        "f": c.K[[0, 1], [0, 1]][:, None],
        "c": c.K[:2, 2][:, None],
        "k": c.dist[[0, 1, 4]][:, None],
        "p": c.dist[2:4][:, None],
        "w": c.size[0],
        "h": c.size[1],
        "name": "cam",
        "id": c.name,
    }


@pytest.fixture
def folder(tmp_path):
    """S9: Walking_1 frames 1 and 6, Eating frame 1 (views 0 and 2 only); S11: one sample."""
    rng = np.random.default_rng(0)
    cams = {"S9": _cameras(0.0), "S11": _cameras(0.3)}
    doc = {(s, c.name): _pkl_entry(c) for s, cs in cams.items() for c in cs}
    (tmp_path / "cameras.pkl").write_bytes(pickle.dumps(doc))
    clips = {
        ("S9", "Walking_1", 1): range(4),
        ("S9", "Walking_1", 6): range(4),
        ("S9", "Eating", 1): (0, 2),
        ("S11", "Directions", 3): (1,),
    }
    world = {k: rng.uniform(-0.4, 0.4, (17, 3)) + [0, 0, 1.0] for k in clips}
    names, S, part = [], [], []
    for (subject, action, frame), views in clips.items():
        for v in views:
            c = cams[subject][v]
            folder = f"{subject}_{action}.{c.name}"
            names.append(f"{subject}/{folder}/{folder}_{frame:06d}.jpg")
            Xc = world[subject, action, frame] @ c.R.T + c.t
            S.append(np.column_stack([Xc, np.ones(17)]))
            part.append(np.column_stack([c.project(world[subject, action, frame]), np.ones(17)]))
    S, part = np.array(S), np.array(part)
    S[0, 13, 3] = 0.0  # S9 Walking_1 frame 1: left wrist unseen in view 0 only
    S[8:10, 2, 3] = 0.0  # S9 Eating frame 1: right knee unseen in both views
    det = part.copy()
    det[:, :, :2] += rng.normal(0, 2.0, (len(det), 17, 2))
    det[:, :, 2] = rng.uniform(0.3, 1.0, (len(det), 17))
    np.savez(
        tmp_path / ANN,
        imgname=np.array(names),
        S=S,
        part=part,
        center=np.zeros((len(S), 2)),
        scale=np.ones(len(S)),
    )
    np.save(tmp_path / DET, det)
    return tmp_path, world, det, part


def _load(root, subject="S9", **kw):
    kw.setdefault("detections", DET)
    return load_h36m(root, subject, annotations=ANN, **kw)


def test_synthetic_subject_regrouped_into_views(folder):
    root, world, det, _ = folder
    data = _load(root)
    assert data.name == "h36m/S9" and data.rig.names == list(CAM_IDS)
    assert data.clips.tolist() == ["Eating", "Walking_1", "Walking_1"]
    assert data.frames.tolist() == [1, 1, 6] and data.gt_skeleton == "h36m17"
    assert data.gt.shape == (3, 1, 17, 3) and data.keypoints.shape == (3, 4, 1, 17, 2)
    np.testing.assert_allclose(data.gt[1, 0], world["S9", "Walking_1", 1], atol=1e-9)
    np.testing.assert_allclose(data.gt[2, 0], world["S9", "Walking_1", 6], atol=1e-9)
    eating = world["S9", "Eating", 1].copy()
    eating[2] = np.nan  # unseen in every view
    np.testing.assert_allclose(data.gt[0, 0], eating, atol=1e-9)
    # Eating frame 1 was filmed by views 0 and 2 only (samples 8 and 9).
    assert np.isnan(data.keypoints[0, [1, 3]]).all() and np.all(data.scores[0, [1, 3]] == 0)
    idx = coco17_by_name(H36M17)
    for j in (COCO17.index("left_wrist"), COCO17.index("right_ankle"), COCO17.index("nose")):
        np.testing.assert_allclose(data.keypoints[0, 2, 0, j], det[9, idx[j], :2])
        assert data.scores[0, 2, 0, j] == det[9, idx[j], 2]
    face = [COCO17.index(n) for n in ("left_eye", "right_eye", "left_ear", "right_ear")]
    assert np.isnan(data.keypoints[..., face, :]).all() and np.all(data.scores[..., face] == 0)


def test_synthetic_sources_and_subjects(folder):
    root, _, _, part = folder
    gt2d = _load(root, source="gt")
    np.testing.assert_allclose(
        gt2d.keypoints[1, 3, 0, COCO17.index("left_knee")], part[3, H36M17.index("left_knee"), :2]
    )
    assert _load(root, source="none").keypoints is None
    assert h36m_subjects(root, ANN) == ["S9", "S11"]
    s11 = _load(root, "S11", source="none")
    assert len(s11) == 1 and s11.clips.tolist() == ["Directions"]
    # Each subject has its own extrinsics.
    assert not np.allclose(s11.rig.centers, _load(root, source="none").rig.centers)


def test_synthetic_bad_inputs(folder):
    root, _, det, _ = folder
    with pytest.raises(InputError, match="subject.*several"):
        load_h36m(root, annotations=ANN, detections=DET)
    with pytest.raises(InputError, match="subject"):
        _load(root, "S2")
    with pytest.raises(InputError, match="source"):
        _load(root, source="pipeline")
    np.save(root / DET, det[:3])
    with pytest.raises(InputError, match=r"h36m_det\.npy.*shape"):
        _load(root)
    with pytest.raises(InputError, match="no such file"):
        _load(root, detections="absent.npy")
    np.savez(root / ANN, imgname=np.array(["S9/not an h36m name.jpg"]), S=np.zeros((1, 17, 4)))
    with pytest.raises(InputError, match=r"imgname\[0\]"):
        _load(root)
    np.savez(
        root / ANN,
        imgname=np.array(["S9/S9_Eating.54138969/S9_Eating.54138969_000001.jpg"]),
        S=np.zeros((1, 16, 4)),
    )
    with pytest.raises(InputError, match=r"'S'.*shape"):
        _load(root)
    np.savez(
        root / ANN,
        imgname=np.array(["S9/S9_Eating.12345678/S9_Eating.12345678_000001.jpg"]),
        S=np.zeros((1, 17, 4)),
    )
    with pytest.raises(InputError, match="12345678"):
        _load(root)


# --- The real fixture (skipped without ../shared/data) ----------------------------------


@pytest.fixture
def real_root(shared_data):
    root = shared_data / "fixtures" / "h36m"
    if not root.is_dir():
        pytest.skip(f"{root} not found")
    return root


@pytest.mark.shared
def test_fixture_shapes_and_metres(real_root):
    subjects = h36m_subjects(real_root)
    assert subjects == ["S1", "S5", "S7", "S8"]
    for s in subjects:
        data = load_h36m(real_root, s)
        assert data.gt.shape == (1, 1, 17, 3) and data.keypoints.shape == (1, 4, 1, 17, 2)
        assert np.isfinite(data.gt).all()
        # Metres, world z up with the floor at 0: thighs and shins 0.3-0.55 m long, the
        # lowest joint within 0.15 m of the floor, the head above the pelvis.
        X = data.gt[0, 0]
        bones = [(1, 2), (2, 3), (4, 5), (5, 6)]
        lengths = np.array([np.linalg.norm(X[a] - X[b]) for a, b in bones])
        assert np.all((lengths > 0.3) & (lengths < 0.55)), lengths
        assert abs(X[:, 2].min()) < 0.15 and X[10, 2] > X[0, 2]
        assert (~np.isnan(data.keypoints).all(axis=(2, 3, 4))).sum() == 1  # one view each


@pytest.mark.shared
def test_fixture_world_gt_reprojects_onto_the_2d(real_root):
    """World ground truth projected with cameras.pkl vs the file's 2D.

    Against the 2D ground truth ``part``: < 0.5 px (measured max 0.19 px), so the camera
    -> world move and the lens model are right. Against the detections: median over the
    13 joints < 10 px and every joint < 40 px (measured: medians 1.5-6.8 px, max 28 px).
    """
    idx = coco17_by_name(H36M17)
    ok = idx >= 0
    for s in h36m_subjects(real_root):
        for source, med, worst in (("gt", 0.5, 0.5), ("detection", 10.0, 40.0)):
            data = load_h36m(real_root, s, source=source)
            v = int(np.flatnonzero(np.isfinite(data.keypoints[0, :, 0, 5, 0]))[0])
            proj = data.rig[v].project(data.gt[0, 0])[idx[ok]]  # (13, 2) COCO order
            err = np.linalg.norm(proj - data.keypoints[0, v, 0, ok], axis=-1)
            assert np.median(err) < med and np.max(err) < worst, (s, source, err)
