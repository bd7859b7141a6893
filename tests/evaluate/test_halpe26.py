"""``rmpl evaluate`` with methods that output HALPE-26: the scored joints stay COCO-17, and
PCP gains a third conversion, the method's own neck and head top ("own").

The PCP values are worked out by hand in the comments; none comes from the code.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
import torch

from rmpl.data.base import MultiViewDataset
from rmpl.evaluate.evalset import EvalSet
from rmpl.evaluate.harness import evaluate, evaluate_poses
from rmpl.evaluate.methods import MonocularMethod, fit_input, make_method
from rmpl.evaluate.registry import parse_methods
from rmpl.evaluate.scoring import PCP_PART_NAMES, pcp_by_actor, pcp_parts_by_actor, shelf15_own
from rmpl.evaluate.tables import benchmark_files, write_files
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.poses import Poses3D
from rmpl.model.lifter import PRESETS, RMPL
from rmpl.skeleton import COCO17, HALPE26, SHELF14

# A standing person (metres, z up): the limbs of Shelf-14 and the ground truth's neck and
# head top. Head: neck -> top, length sqrt(0.0375^2 + 0.3^2) = 0.3006 m (half 0.1503).
# Torso: neck -> mid-hip (0, 0, 0.9), length sqrt(0.0375^2 + 0.65^2) = 0.6511 (half 0.3255).
LIMBS = {
    "left_shoulder": (0.2, 0.0, 1.4),
    "right_shoulder": (-0.2, 0.0, 1.4),
    "left_elbow": (0.25, 0.0, 1.12),
    "right_elbow": (-0.25, 0.0, 1.12),
    "left_wrist": (0.3, 0.0, 0.86),
    "right_wrist": (-0.3, 0.0, 0.86),
    "left_hip": (0.1, 0.0, 0.9),
    "right_hip": (-0.1, 0.0, 0.9),
    "left_knee": (0.1, 0.0, 0.48),
    "right_knee": (-0.1, 0.0, 0.48),
    "left_ankle": (0.1, 0.0, 0.05),
    "right_ankle": (-0.1, 0.0, 0.05),
}
GT_NECK, GT_TOP = (0.0, 0.0375, 1.55), (0.0, 0.0375, 1.85)


def _gt_shelf(shift=0.0) -> np.ndarray:
    gt = np.zeros((14, 3))
    for i, name in enumerate(SHELF14.joints[:12]):
        gt[i] = LIMBS[name]
    gt[12], gt[13] = GT_NECK, GT_TOP
    return gt + [shift, 0, 0]


def _halpe(neck=GT_NECK, top=GT_TOP, shift=0.0) -> np.ndarray:
    """A HALPE-26 pose with the limbs above, the given neck and head top; the face at a
    point that no conversion of ours would turn into the ground truth's head."""
    x = np.zeros((26, 3))
    for name, p in LIMBS.items():
        x[HALPE26.index(name)] = p
    for name in ("nose", "left_eye", "right_eye", "left_ear", "right_ear"):
        x[HALPE26.index(name)] = (0.0, 0.0, 3.0)  # 1.2 m above the head: every head is wrong
    x[HALPE26.index("neck")], x[HALPE26.index("head_top")] = neck, top
    x[HALPE26.index("mid_hip")] = (0.0, 0.0, 0.9)
    return x + [shift, 0, 0]


# Actor 1: own neck and head top exact -> all ten parts right (PCP 100).
# Actor 2: own neck 0.35 m off in x, head top exact -> head: mean end error 0.175 > 0.1503,
# wrong; torso: 0.35 / 2 = 0.175 <= 0.3255, right -> PCP (9 x 100) / 10 = 90.
# Actor 2's second pose: neck exact, head top 0.25 m off -> head 0.125 <= 0.1503, right:
# over its two poses the head is right once (50%), PCP (9 x 100 + 50) / 10 = 95.
NECK_OFF = (0.35, 0.0375, 1.55)
TOP_OFF = (0.0, 0.0375, 2.10)


def test_own_head_top_and_neck_by_hand():
    y = shelf15_own(_halpe(neck=NECK_OFF))
    assert y.shape == (15, 3)
    np.testing.assert_allclose(y[SHELF14.index("neck")], NECK_OFF)
    np.testing.assert_allclose(y[SHELF14.index("head_top")], GT_TOP)
    np.testing.assert_allclose(y[14], (0.0, 0.0, 0.9))  # mid-hip: the mean of the hips
    with pytest.raises(ValueError, match="26"):
        shelf15_own(np.zeros((17, 3)))


def test_own_pcp_per_part_by_hand():
    pred = np.stack([_halpe(), _halpe(neck=NECK_OFF), _halpe(top=TOP_OFF)])
    native = np.stack([_gt_shelf()] * 3)
    person = np.array(["actor 1", "actor 2", "actor 2"])
    parts = pcp_parts_by_actor(pred, native, person, "own")
    assert parts["actor 1"] == dict.fromkeys(PCP_PART_NAMES, 100.0)
    assert parts["actor 2"] == dict.fromkeys(PCP_PART_NAMES, 100.0) | {"head": 50.0}
    assert pcp_by_actor(pred, native, person, "own") == {"actor 1": 100.0, "actor 2": 95.0}
    # The face 1.2 m above the head: the published head is wrong for every pose.
    lit = pcp_parts_by_actor(pred[:, :17], native, person, "published")
    assert lit["actor 1"]["head"] == 0.0 and lit["actor 2"]["head"] == 0.0


def _tiny_shelf() -> EvalSet:
    """Two frames, two actors (ids 1 and 2, actor 2 two metres along x), two cameras."""
    K = np.array([[1000.0, 0, 500], [0, 1000, 500], [0, 0, 1]])
    rig = Rig(tuple(Camera(K, np.eye(3), np.array([i, 0, 5.0]), name=str(i)) for i in range(2)))
    gt = np.stack([_gt_shelf(), _gt_shelf(2.0)])  # (P, 14, 3)
    gt = np.stack([gt, gt])  # (T, P, 14, 3)
    keypoints = np.zeros((2, 2, 2, 17, 2))  # (T, V, N, 17, 2)
    data = MultiViewDataset(
        rig, np.array([0, 1]), gt, "shelf14", keypoints, np.ones((2, 2, 2, 17)), "shelf",
        person_ids=np.array([1, 2]),
    )  # fmt: skip
    return EvalSet((data,), "shelf", "2D: none (tiny test set)", "given", pcp=True)


def _read(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_own_pcp_columns_through_the_files(tmp_path):
    """A HALPE-26 result (rmpl run output) beside a COCO-17 one: own PCP for the first only."""
    evset = _tiny_shelf()
    # frame 0: actor 1 exact, actor 2 neck off; frame 1: actor 1 exact, actor 2 top off.
    halpe = np.stack([
        np.stack([_halpe(), _halpe(neck=NECK_OFF, shift=2.0)]),
        np.stack([_halpe(), _halpe(top=TOP_OFF, shift=2.0)]),
    ])  # fmt: skip
    results = {
        "halpe": Poses3D(points=halpe, frames=np.array([0, 1]), skeleton="halpe26"),
        "coco": Poses3D(points=halpe[:, :, :17].copy(), frames=np.array([0, 1])),
    }
    ev = evaluate_poses(evset, results)
    assert ev.skeletons == {"halpe": "halpe26", "coco": "coco17"}
    files = benchmark_files(ev, "rmpl evaluate --dataset shelf --poses ...")
    write_files(tmp_path, files)
    rows = {r["method"]: r for r in _read(tmp_path / "results.csv")}
    cols = list(rows["halpe"])
    assert cols[-3:] == ["pcp_own_actor1", "pcp_own_actor2", "pcp_own_mean"]
    assert cols[-6:-3] == ["pcp_lit_actor1", "pcp_lit_actor2", "pcp_lit_mean"]
    own = [float(rows["halpe"][c]) for c in cols[-3:]]
    assert own == [100.0, 95.0, 97.5]
    assert all(np.isnan(float(rows["coco"][c])) for c in cols[-3:])
    # The scored joints are COCO-17: both results have the same MPJPE (0: exact limbs).
    assert float(rows["halpe"]["mpjpe"]) == float(rows["coco"]["mpjpe"]) == 0.0
    people = {(r["method"], r["person"]): r for r in _read(tmp_path / "per_person.csv")}
    assert float(people["halpe", "actor 2"]["pcp_own"]) == 95.0
    assert float(people["halpe", "actor 2"]["pcp_own_head"]) == 50.0
    assert float(people["halpe", "actor 2"]["pcp_own_torso"]) == 100.0
    assert np.isnan(float(people["coco", "actor 2"]["pcp_own"]))
    text = files["results.md"]
    assert "PCP, own head (pcp_own_*)" in text and "PCP mean, own head (%)" in text
    # Per part: three conversions for the HALPE-26 result, two for the COCO-17 one.
    part_rows = [line for line in text.splitlines() if line.startswith("| all |")]
    assert sum("| own |" in line for line in part_rows) == 2  # actors 1 and 2
    assert not any("| coco |" in line and "| own |" in line for line in part_rows)


def test_coco17_only_has_no_own_columns(tmp_path):
    evset = _tiny_shelf()
    pts = np.stack([np.stack([_halpe()[:17], _halpe(shift=2.0)[:17]])] * 2)
    ev = evaluate_poses(evset, {"coco": Poses3D(points=pts, frames=np.array([0, 1]))})
    files = benchmark_files(ev, "rmpl evaluate")
    assert "own" not in files["results.md"]
    assert not any(k.startswith("pcp_own") for k in files["results.csv"][0])
    assert not any(k.startswith("pcp_own") for k in files["per_person.csv"][0])


# --- methods with a 26-joint model ------------------------------------------------------


@pytest.fixture(scope="module")
def halpe_model(tmp_path_factory):
    """A random (untrained) 26-joint per-frame checkpoint."""
    from rmpl.training.loop import save_checkpoint

    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("halpe") / "model"
    save_checkpoint(RMPL(PRESETS["tiny"].with_(num_joints=26, skeleton="halpe26")), path)
    return path


def _rig(views=3) -> Rig:
    K = np.array([[900.0, 0, 480], [0, 900, 360], [0, 0, 1]])
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views
        R, t = look_at(np.array([5 * np.cos(a), 5 * np.sin(a), 2.0]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(960, 720), name=f"cam{v}"))
    return Rig(tuple(cams))


def _people(J: int, views=3, n=4, seed=0):
    rng = np.random.default_rng(seed)
    rig = _rig(views)
    X = rng.uniform(-0.3, 0.3, (n, J, 3)) + [0, 0, 1.0]
    kp = rig.project(X.reshape(-1, 3)).reshape(views, n, J, 2).transpose(1, 0, 2, 3)
    return kp, np.full((n, views, J), 0.9), X, rig


def test_fit_input():
    kp, sc = np.zeros((2, 3, 26, 2)), np.ones((2, 3, 26))
    a, b = fit_input(kp, sc, 17)
    assert a.shape == (2, 3, 17, 2) and b.shape == (2, 3, 17)
    assert fit_input(kp, sc, 26)[0].shape == (2, 3, 26, 2)
    assert fit_input(kp[..., :17, :], sc[..., :17], 26)[0].shape == (2, 3, 17, 2)
    with pytest.raises(ValueError, match="25 joints"):
        fit_input(kp[..., :25, :], sc[..., :25], 17)


@pytest.mark.parametrize("J", [17, 26])
def test_triangulation_baselines_score_coco17(J):
    kp, sc, X, rig = _people(J)
    for name in ("triangulate", "robust"):
        pred = make_method(name)(kp, sc, rig)
        assert pred.shape == (4, 17, 3)
        np.testing.assert_allclose(pred, X[:, :17], atol=1e-6)


@pytest.mark.parametrize("J", [17, 26])
def test_rmpl_methods_with_a_26_joint_model(halpe_model, J):
    kp, sc, X, rig = _people(J)
    pred = make_method(f"rmpl:{halpe_model}")(kp, sc, rig)
    assert pred.shape == (4, 26, 3) and np.isfinite(pred).all()
    floor = MonocularMethod(model=str(halpe_model))
    assert floor(kp, sc, rig).shape == (4, 26, 3)  # more views: the plain lifter
    one = floor(kp[:, :1], sc[:, :1], rig[[0]])  # one view: depth from the cues
    assert one.shape == (4, 26, 3)
    seq = MonocularMethod(model=str(halpe_model))  # with "time": tracks of one view
    pred, at = seq(kp[:, :1], sc[:, :1], np.arange(4), 4, rig[[0]], 25.0)
    assert pred.shape[1:] == (26, 3) and len(pred) == len(at)
    # The shipped COCO-17 model takes HALPE-26 2D (its first 17 joints).
    assert make_method("rmpl")(kp, sc, rig).shape == (4, 17, 3)


def _walk(J: int, T=12, views=3, seed=0):
    """One person walking: per-frame rows kp (T, V, J, 2), sc, frame (T,), the 3D, rig."""
    rng = np.random.default_rng(seed)
    rig = _rig(views)
    body = rng.uniform(-0.25, 0.25, (J, 3)) + [0, 0, 1.0]
    X = body + np.c_[np.arange(T) / 25, np.zeros(T), np.zeros(T)][:, None]  # (T, J, 3)
    kp = rig.project(X.reshape(-1, 3)).reshape(views, T, J, 2).transpose(1, 0, 2, 3)
    return kp, np.full((T, views, J), 0.9), np.arange(T), X, rig


def test_sequence_methods_with_26_joint_models(halpe_model, tmp_path):
    from rmpl.model.temporal import TemporalConfig, TemporalRMPL
    from rmpl.training.loop import load_checkpoint
    from rmpl.training.temporal import save_temporal

    frame_model, _ = load_checkpoint(halpe_model)
    torch.manual_seed(0)
    save_temporal(
        TemporalRMPL(frame_model, TemporalConfig(dim=16, depth=1, window=8)), tmp_path / "t"
    )
    methods = parse_methods(f"triangulate+filter,rmpl:temporal:{tmp_path / 't'}")
    methods["rmpl+filter"] = parse_methods("rmpl+filter")["rmpl+filter"]
    from rmpl.evaluate.sequences import SequenceMethod

    methods["rmpl:halpe+filter"] = SequenceMethod(f"rmpl:{halpe_model}")
    for J in (17, 26):
        kp, sc, frame, X, rig = _walk(J)
        for name, method in methods.items():
            pred, at = method(kp, sc, frame, len(frame), rig, 25.0)
            expect = 17 if name in ("triangulate+filter", "rmpl+filter") else 26
            assert pred.shape == (12, expect, 3), (name, J)
            assert at.tolist() == list(range(12)) and np.isfinite(pred).all(), (name, J)


def test_harness_keeps_coco17_and_the_extra_joints(halpe_model):
    """Through :func:`evaluate`: the COCO-17 predictions of a HALPE-26 method and its extra
    joints, split; a triangulation's extra joints are NaN."""
    evset = _tiny_shelf()
    part = evset.parts[0]
    # 2D: the ground truth's COCO-17 limbs projected (the face missing).
    kp = np.full((2, 2, 2, 17, 2), np.nan)
    sc = np.zeros((2, 2, 2, 17))
    idx = [COCO17.index(n) for n in SHELF14.joints[:12]]
    for v in range(2):
        kp[:, v, :, :][..., idx, :] = part.rig[v].project(part.gt[..., :12, :])  # (T, P, 12, 2)
        sc[:, v, :, :][..., idx] = 1.0
    data = MultiViewDataset(part.rig, part.frames, part.gt, "shelf14", kp, sc, "shelf",
                            person_ids=part.person_ids)  # fmt: skip
    evset = EvalSet((data,), "shelf", "2D: projected", "given", pcp=True)
    methods = {
        "triangulate": make_method("triangulate"),
        "halpe": make_method(f"rmpl:{halpe_model}"),
    }
    ev = evaluate(evset, methods, {"all": [(0, 1)]}, progress=False)
    assert ev.skeletons == {"triangulate": "coco17", "halpe": "halpe26"}
    tri, own = ev.preds["all", 0, "triangulate"][0], ev.extra["all", 0, "halpe"][0]
    assert tri.shape == (4, 17, 3) and ev.preds["all", 0, "halpe"][0].shape == (4, 17, 3)
    assert own.shape == (4, 9, 3) and np.isfinite(own).all()
    assert np.isnan(ev.extra["all", 0, "triangulate"][0]).all()
    np.testing.assert_allclose(tri[:, idx], part.gt[..., :12, :].reshape(4, 12, 3), atol=1e-6)
    rows = benchmark_files(ev, "x")["results.csv"]
    assert "pcp_own_mean" in rows[0] and np.isnan(rows[0]["pcp_own_mean"])
