"""Scores of a simulated capture's stages: cases whose answers are known by construction."""

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rmpl.calibration.people_synth import ring_rig
from rmpl.calibration.sync import Sync
from rmpl.geometry.camera import Camera, Rig
from rmpl.simulate.score import (
    angle_errors,
    calibration_errors,
    detection_scores,
    frames_on_common_clock,
    identity_scores,
    joint_angles,
    pose_scores,
    sync_errors,
)
from rmpl.skeleton import HALPE26

# --------------------------------------------------------------------------- calibration


def _moved(rig: Rig, scale: float, Q: np.ndarray, shift: np.ndarray) -> Rig:
    """The same cameras in a world X' = scale Q X + shift."""
    cams = []
    for c in rig:
        R = c.R @ Q.T
        cams.append(Camera(c.K, R, -R @ (scale * Q @ c.center + shift), c.dist, c.size, c.name))
    return Rig(tuple(cams))


@pytest.mark.parametrize("num_views", [2, 4])
def test_calibration_of_a_moved_world_is_exact_after_alignment(num_views):
    truth = ring_rig(num_views, rng=1)
    Q = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
    found = _moved(truth, 1.7, Q, np.array([1.0, -2.0, 0.5]))
    got = calibration_errors(found, truth)
    assert got["scale"] == pytest.approx(1.7, rel=1e-9)
    assert got["rotation_deg"]["max"] < 1e-5
    assert got["centre_mm"]["max"] < 1e-5
    assert got["focal_pct"]["max"] == 0 and got["principal_px"]["max"] == 0
    assert got["note"] is None and got["missing"] == [] and got["extra"] == []
    json.dumps(got)
    # Without alignment every camera is off by the world's turn.
    same = calibration_errors(found, truth, align=False)
    turn = np.degrees(np.linalg.norm([0.3, -1.1, 0.7]))
    assert same["rotation_deg"]["mean"] == pytest.approx(turn, abs=1e-6)
    assert same["scale"] is None


def test_calibration_one_camera_turned_one_degree():
    truth = ring_rig(5, rng=2)
    cams = list(truth)
    c = cams[2]
    R = Rotation.from_rotvec(np.radians(1.0) * np.array([0.6, 0.0, 0.8])).as_matrix() @ c.R
    cams[2] = Camera(c.K, R, -R @ c.center, c.dist, c.size, c.name)
    K = cams[1].K.copy()
    K[0, 0] *= 1.02
    K[:2, 2] += [3.0, 4.0]
    cams[1] = Camera(K, cams[1].R, cams[1].t, cams[1].dist, cams[1].size, cams[1].name)
    found = Rig(tuple(cams[:4]))  # cam4 lost
    for align in (False, True):
        got = calibration_errors(found, truth, align=align)
        rot = {n: e["rotation_deg"] for n, e in got["cameras"].items()}
        assert rot["cam2"] == pytest.approx(1.0, abs=0.05 if align else 1e-6)
        assert max(rot[n] for n in ("cam0", "cam1", "cam3")) < (0.05 if align else 1e-6)
        assert got["cameras"]["cam1"]["focal_pct"] == pytest.approx(2.0)
        assert got["cameras"]["cam1"]["principal_px"] == pytest.approx(5.0)
        assert got["principal_px"]["mean"] == pytest.approx(5.0 / 4)
        assert got["missing"] == ["cam4"] and "cam4" in got["note"]
    assert got["scale"] == pytest.approx(1.0, abs=1e-3)


def test_calibration_without_a_common_camera_says_so():
    truth = ring_rig(2, rng=3)
    got = calibration_errors(Rig((truth[0],)), truth)
    assert got["cameras"]["cam0"]["rotation_deg"] is None
    assert got["scale"] is None and "alignment" in got["note"]


# --------------------------------------------------------------------------- sync


def test_sync_errors_with_a_different_reference_first():
    fps = np.array([30.0, 60.0, 25.0])
    truth = Sync(["a", "b", "c"], fps, np.array([0.0, 0.5, -0.2]), np.ones(3))
    e_a = -0.3 / 60  # a's clock found early: b appears 0.3 of its frames late
    e_c = 1 / 25  # c found one of its frames late
    found = Sync(["b", "a", "c"], fps[[1, 0, 2]], np.array([0.0, -0.5 + e_a, -0.7 + e_c]),
                 np.ones(3))  # fmt: skip
    got = sync_errors(found, truth)
    cams = got["cameras"]
    assert got["reference"] == "a" and not got["refused"]
    assert cams["a"]["error_frames"] == pytest.approx(0.0) and cams["a"]["exact"]
    assert cams["b"]["true_frames"] == pytest.approx(30.0)
    assert cams["b"]["error_frames"] == pytest.approx(-e_a * 60) and cams["b"]["exact"]
    assert cams["c"]["error_frames"] == pytest.approx((e_c - e_a) * 25)
    assert not cams["c"]["exact"] and not got["all_exact"]
    assert got["max_abs_error_frames"] == pytest.approx((e_c - e_a) * 25)
    json.dumps(got)


def test_sync_refused():
    truth = Sync(["a", "b"], np.array([30.0, 30.0]), np.array([0.0, 0.1]), np.ones(2))
    got = sync_errors(None, truth)
    assert got["refused"] and got["cameras"] == {"a": None, "b": None} and got["note"]


# --------------------------------------------------------------------------- detection


def _detection_case(rng, extra_joints: int = 0):
    """2 frames x 2 views, 4 true people (the last with 2 visible joints); person 2
    dropped in (0, 0), a ghost in (1, 0) and (1, 1); every scored joint 3 px off."""
    T, V, P, N, J = 2, 2, 4, 4, 17
    centres = np.array([[200.0, 400.0], [500.0, 400.0], [800.0, 400.0], [1200.0, 400.0]])
    truth = centres[None, None, :, None] + rng.uniform(-50, 50, (T, V, P, J, 2))
    visible = np.ones((T, V, P, J), bool)
    visible[:, :, 3, 2:] = False
    visible[:, :, 0, 5] = False  # hidden: its detection does not count
    kp = np.full((T, V, N, J + extra_joints, 2), np.nan)
    sc = np.zeros((T, V, N, J + extra_joints))
    for t in range(T):
        for v in range(V):
            people = [] if (t, v) == (0, 0) else [2]
            for n, p in zip(rng.permutation(3), [0, 1, *people], strict=False):
                a = rng.uniform(0, 2 * np.pi, J)
                kp[t, v, n, :J] = truth[t, v, p] + 3 * np.stack([np.cos(a), np.sin(a)], -1)
                sc[t, v, n, :J] = rng.uniform(0.6, 1.0, J)
                kp[t, v, n, J:] = truth[t, v, p, 0] + 500  # not on the truth's joint set
                sc[t, v, n, J:] = 0.9
            slot0 = np.nonzero(np.isfinite(kp[t, v, :, 0, 0]))[0]
            who = [int(np.argmin(np.abs(kp[t, v, n, 0, 0] - truth[t, v, :3, 0, 0]))) for n in slot0]
            kp[t, v, slot0[who.index(0)], 5] += 40.0  # the hidden joint, far off
            low = slot0[who.index(1)]
            kp[t, v, low, 7] += 60.0
            sc[t, v, low, 7] = 0.3  # below the threshold: not a detection
    for t, v in [(1, 0), (1, 1)]:
        kp[t, v, 3, :J] = [1500.0, 900.0] + rng.uniform(-40, 40, (J, 2))
        sc[t, v, 3, :J] = 0.8
    return kp, sc, truth, visible


@pytest.mark.parametrize("extra_joints", [0, 9])
def test_detection_recall_precision_and_error(extra_joints):
    kp, sc, truth, visible = _detection_case(np.random.default_rng(4), extra_joints)
    got = detection_scores(kp, sc, truth, visible, views=["left", "right"])
    assert got["people_in_view"] == 12 and got["detections"] == 13
    assert got["recall"] == pytest.approx(11 / 12)
    assert got["precision"] == pytest.approx(11 / 13)
    assert got["joints_scored"] == 16 * 4 + 16 * 4 + 17 * 3
    for k in ("median", "mean", "p90"):
        assert got["error_px"][k] == pytest.approx(3.0)
    assert got["joints"] == "coco17"
    assert got["per_joint_px"]["left_wrist"]["mean"] == pytest.approx(3.0)
    left, right = got["views"]["left"], got["views"]["right"]
    assert left["recall"] == pytest.approx(5 / 6) and left["precision"] == pytest.approx(5 / 6)
    assert right["recall"] == 1.0 and right["precision"] == pytest.approx(6 / 7)
    json.dumps(got)


# --------------------------------------------------------------------------- identities


def _two_people(T=10, J=17, gap=2.0, seed=5):
    rng = np.random.default_rng(seed)
    body = rng.uniform(-0.3, 0.3, (J, 3)) + [0, 0, 1]
    walk = np.linspace(0, 1, T)[:, None, None] * [0.5, 0.2, 0]  # (T, 1, 3)
    truth = np.stack([body + walk[:, 0][:, None], body + walk[:, 0][:, None] + [gap, 0, 0]], 1)
    return truth  # (T, 2, J, 3)


def _swapped(truth, at):
    pred = truth.copy()
    pred[at:] = truth[at:, ::-1]
    return pred


@pytest.mark.parametrize("at", [5, 7])
def test_identity_one_swap(at):
    truth = _two_people()
    T = len(truth)
    got = identity_scores(_swapped(truth, at), truth)
    idtp = 2 * max(at, T - at)  # each track keeps the person it follows longest
    assert got["idtp"] == idtp and got["idfp"] == got["idfn"] == 2 * T - idtp
    assert got["idf1"] == pytest.approx(2 * idtp / (4 * T))
    assert got["tracks_per_person"] == [2, 2] and got["num_tracks"] == 2
    json.dumps(got)


def test_identity_ghost_track_and_absent_frames():
    truth = _two_people()
    pred = np.full((10, 3, 17, 3), np.nan)
    pred[:, :2] = _swapped(truth, 5)
    pred[:4, 2] = truth[:4, 0] + [10.0, 0, 0]  # a ghost, 4 frames, nobody near
    pred[8:, 0] = np.nan  # track 0 lost for the last 2 frames (the truth is still there)
    got = identity_scores(pred, truth)
    # track 0 - person 0: frames 0-4 (5); track 1 - person 1: frames 0-4 (5)
    assert got["idtp"] == 10 and got["num_tracks"] == 3
    assert got["idfp"] == (18 + 4) - 10 and got["idfn"] == 20 - 10
    assert got["idf1"] == pytest.approx(20 / (22 + 20))
    assert got["assignment"] in ([0, 1], [1, 0])


# --------------------------------------------------------------------------- 3D poses


def test_pose_scores_with_known_offsets():
    truth = _two_people(T=6)
    pred = np.empty_like(truth)
    pred[:, 1] = truth[:, 0] + [0.03, 0, 0]
    pred[:, 0] = truth[:, 1] + [0, 0.08, 0]
    pred[:, 1, 3] = np.nan  # person 0's joint 3 never predicted
    got = pose_scores(pred, truth)
    p0, p1, overall = got["people"][0], got["people"][1], got["overall"]
    assert p0["track"] == 1 and p1["track"] == 0
    assert p0["mpjpe_mm"] == pytest.approx(30) and p1["mpjpe_mm"] == pytest.approx(80)
    assert p0["coverage"] == pytest.approx(16 / 17) and p1["coverage"] == 1.0
    assert p0["pck"]["50"] == pytest.approx(100 * 16 / 17) and p1["pck"]["50"] == 0
    assert p1["pck"]["100"] == 100
    assert overall["mpjpe_mm"] == pytest.approx((30 * 16 + 80 * 17) / 33)
    assert overall["pck"]["50"] == pytest.approx(100 * 16 / 34)
    assert overall["coverage"] == pytest.approx(33 / 34)
    some = pose_scores(pred, truth, joints=[0, 1, 2])
    assert some["people"][0]["coverage"] == 1.0 and some["overall"]["joints_true"] == 36
    json.dumps(got)


def test_pose_scores_a_swap_costs():
    truth = _two_people(T=10, gap=2.0)
    got = pose_scores(_swapped(truth, 5), truth)
    # Each person's track is right half the time and 2 m off (the other person) the rest.
    assert got["overall"]["mpjpe_mm"] == pytest.approx(1000.0)
    assert got["overall"]["pck"]["150"] == pytest.approx(50.0)


def test_frames_on_common_clock():
    a, b = frames_on_common_clock(np.array([10, 12, 13, 20]), np.arange(11, 16))
    assert a.tolist() == [1, 2] and b.tolist() == [1, 2]


# --------------------------------------------------------------------------- joint angles


def _legs(hip_deg: float, knee_deg: float, turn: np.ndarray | None = None) -> np.ndarray:
    """HALPE-26 hips, knees, ankles, neck and shoulders of a body facing +y (z up), both
    legs with the given hip and knee flexion, optionally turned and moved."""
    x = np.full((26, 3), np.nan)
    H = HALPE26.index
    x[H("neck")] = [0, 0, 1.5]
    x[H("left_shoulder")], x[H("right_shoulder")] = [-0.2, 0, 1.45], [0.2, 0, 1.45]
    a, b = np.radians(hip_deg), np.radians(hip_deg - knee_deg)
    for side, sx in (("left", -0.1), ("right", 0.1)):
        x[H(f"{side}_hip")] = [sx, 0, 1.0]
        x[H(f"{side}_knee")] = x[H(f"{side}_hip")] + 0.45 * np.array([0, np.sin(a), -np.cos(a)])
        x[H(f"{side}_ankle")] = x[H(f"{side}_knee")] + 0.4 * np.array([0, np.sin(b), -np.cos(b)])
    if turn is not None:
        x = x @ turn.T + [1.0, 2.0, 0.0]
    return x


@pytest.mark.parametrize(("hip", "knee"), [(0, 0), (0, 90), (30, 60), (-15, 10), (90, 90)])
def test_joint_angles_of_known_legs(hip, knee):
    turn = Rotation.from_rotvec([0.2, -0.4, 2.0]).as_matrix()
    for pose in (_legs(hip, knee), _legs(hip, knee, turn)):
        got = joint_angles(pose)
        for side in ("left", "right"):
            assert float(got[f"knee_flexion_{side}"]) == pytest.approx(knee, abs=1e-6)
            assert float(got[f"hip_flexion_{side}"]) == pytest.approx(hip, abs=1e-6)


def test_angle_errors():
    truth = np.stack([_legs(10, 20), _legs(0, 0), _legs(40, 5)])
    pred = np.stack([_legs(10, 50), _legs(0, 0), _legs(40, 35)])
    pred[1] = np.nan  # not estimated: left out
    got = angle_errors(pred, truth)
    assert got["knee_flexion_left"]["mae_deg"] == pytest.approx(30)
    assert got["knee_flexion_left"]["rmse_deg"] == pytest.approx(30)
    assert got["knee_flexion_right"]["poses"] == 2
    assert got["hip_flexion_left"]["mae_deg"] == pytest.approx(0, abs=1e-9)
    json.dumps(got)
