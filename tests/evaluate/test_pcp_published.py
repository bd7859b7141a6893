"""PCP with the published COCO-17 -> Shelf-14 conversion (coco2shelf3D) and PCP per part.

The expected values are worked out by hand in the comments; none comes from the code.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

from rmpl.data.base import MultiViewDataset
from rmpl.evaluate.evalset import EvalSet
from rmpl.evaluate.harness import evaluate_poses
from rmpl.evaluate.scoring import (
    PCP_PART_NAMES,
    pcp_by_actor,
    pcp_parts_by_actor,
    shelf14_published,
)
from rmpl.evaluate.tables import benchmark_files, write_files
from rmpl.geometry.camera import Camera, Rig
from rmpl.io.poses import Poses3D
from rmpl.skeleton import COCO17, SHELF14


def _coco(**joints) -> np.ndarray:
    """A COCO-17 pose (17, 3) from name -> point; the joints not given are at the origin."""
    x = np.zeros((17, 3))
    for name, point in joints.items():
        x[COCO17.index(name)] = point
    return x


# ms = (0, 0, 1.4), n - ms = d = (0.04, 0.12, 0.24), ec = (0.02, 0.02, 1.6).
HEAD = {
    "left_shoulder": (0.2, 0.1, 1.4),
    "right_shoulder": (-0.2, -0.1, 1.4),
    "nose": (0.04, 0.12, 1.64),
    "left_ear": (0.1, 0.02, 1.6),
    "right_ear": (-0.06, 0.02, 1.6),
}
# mvpose: top = ms + d * [0.75, 0.75, 1.5] = (0.03, 0.09, 1.76); neck = ms + d / 2.
MVPOSE_TOP, MVPOSE_NECK = (0.03, 0.09, 1.76), (0.02, 0.06, 1.52)
# VoxelPose: hb = (ms + ec) / 2 = (0.01, 0.01, 1.5), ht = 2 ec - hb = (0.03, 0.03, 1.7);
# top = 0.75 (0.03, 0.09, 1.76) + 0.25 ht, neck = 0.75 (0.02, 0.06, 1.52) + 0.25 hb.
VOXELPOSE_TOP, VOXELPOSE_NECK = (0.03, 0.075, 1.745), (0.0175, 0.0475, 1.515)


def test_published_head_top_and_neck_by_hand():
    x = _coco(**HEAD)
    y = shelf14_published(x)
    assert y.shape == (14, 3)
    neck, top = SHELF14.index("neck"), SHELF14.index("head_top")
    np.testing.assert_allclose(y[top], VOXELPOSE_TOP, atol=1e-12)
    np.testing.assert_allclose(y[neck], VOXELPOSE_NECK, atol=1e-12)
    mv = shelf14_published(x, ears=False)
    np.testing.assert_allclose(mv[top], MVPOSE_TOP, atol=1e-12)
    np.testing.assert_allclose(mv[neck], MVPOSE_NECK, atol=1e-12)


def test_published_limbs_follow_the_evaluation_code_indices():
    x = np.random.default_rng(0).normal(size=(2, 3, 17, 3))
    y = shelf14_published(x)
    assert y.shape == (2, 3, 14, 3)
    # coco2shelf3D: COCO [16, 14, 12, 11, 13, 15, 10, 8, 6, 5, 7, 9] are Shelf 0-11.
    limbs = [16, 14, 12, 11, 13, 15, 10, 8, 6, 5, 7, 9]
    np.testing.assert_array_equal(y[..., :12, :], x[..., limbs, :])


def test_published_up_axis():
    """In a y-up world (x, y, z) -> (x, z, -y) the head top is the same point, rotated."""
    x = _coco(**HEAD)[:, [0, 2, 1]] * [1, 1, -1]
    y = shelf14_published(x, up=(0.0, 1.0, 0.0))
    np.testing.assert_allclose(y[SHELF14.index("head_top")], (0.03, 1.745, -0.075), atol=1e-12)
    np.testing.assert_allclose(y[SHELF14.index("neck")], (0.0175, 1.515, -0.0475), atol=1e-12)
    # With z taken as up in that world, the head top is wrong: the up axis matters.
    z = shelf14_published(x)
    assert np.linalg.norm(z[SHELF14.index("head_top")] - y[SHELF14.index("head_top")]) > 0.05


def test_published_missing_ears_or_nose_give_nan_head_points():
    x = _coco(**HEAD)
    x[COCO17.index("left_ear")] = np.nan
    y = shelf14_published(x)
    assert np.isnan(y[12:]).all() and np.isfinite(y[:12]).all()
    assert np.isfinite(shelf14_published(x, ears=False)[12:]).all()  # mvpose needs no ears
    x[COCO17.index("nose")] = np.nan
    assert np.isnan(shelf14_published(x, ears=False)[12:]).all()


def test_published_bad_input():
    with pytest.raises(ValueError, match=r"\(\*, 17, 3\)"):
        shelf14_published(np.zeros((14, 3)))
    with pytest.raises(ValueError, match="up"):
        shelf14_published(np.zeros((17, 3)), up=(0.0, 0.0, 0.0))


# --- PCP per part on a hand-made case -------------------------------------------------

# A standing person: shoulders at z 1.4, hips at z 0.9, ears high (z 2.0).
BODY = {
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
    "nose": (0.0, 0.1, 1.6),
    "left_ear": (0.08, 0.0, 2.0),
    "right_ear": (-0.08, 0.0, 2.0),
}
# ms = (0, 0, 1.4), d = (0, 0.1, 0.2), ec = (0, 0, 2.0), hb = (0, 0, 1.7), ht = (0, 0, 2.3).
# Published: top = 0.75 (0, 0.075, 1.7) + 0.25 ht = (0, 0.05625, 1.85),
#            neck = 0.75 (0, 0.05, 1.5) + 0.25 hb = (0, 0.0375, 1.55).
# Derived (rmpl.skeleton): top = 2 ec - ms = (0, 0, 2.6), neck = 0.7 ms + 0.3 ec = (0, 0, 1.58).
# The ground truth's neck and head top are the published points, so the published head is
# right; the derived head top is 0.75 m off (mean end error 0.40 m > half the 0.30 m head):
# wrong. The torso (neck to mid-hip, 0.65 m) stays right with both (derived neck 48 mm off).
GT_NECK, GT_TOP = (0.0, 0.0375, 1.55), (0.0, 0.05625, 1.85)


def _gt_shelf() -> np.ndarray:
    gt = np.zeros((14, 3))
    for i, name in enumerate(SHELF14.joints[:12]):
        gt[i] = BODY[name]
    gt[12], gt[13] = GT_NECK, GT_TOP
    return gt


def _case():
    """Three poses: actor 1 twice (its right wrist 1 m off in the second), actor 2 once."""
    pred = np.stack([_coco(**BODY)] * 3)
    pred[1, COCO17.index("right_wrist"), 0] += 1.0
    native = np.stack([_gt_shelf()] * 3)
    person = np.array(["actor 1", "actor 1", "actor 2"])
    return pred, native, person


def test_pcp_per_part_by_hand():
    pred, native, person = _case()
    lit = pcp_parts_by_actor(pred, native, person, "published")
    derived = pcp_parts_by_actor(pred, native, person, "derived")
    assert set(lit) == set(derived) == {"actor 1", "actor 2"}
    assert list(lit["actor 1"]) == list(PCP_PART_NAMES)
    expected = dict.fromkeys(PCP_PART_NAMES, 100.0) | {"right_lower_arm": 50.0}
    assert lit["actor 1"] == expected
    assert derived["actor 1"] == expected | {"head": 0.0}
    assert lit["actor 2"] == dict.fromkeys(PCP_PART_NAMES, 100.0)
    assert derived["actor 2"] == dict.fromkeys(PCP_PART_NAMES, 100.0) | {"head": 0.0}
    # PCP is the mean over the ten parts: (9 x 100 + 50) / 10 and (8 x 100 + 0 + 50) / 10.
    assert pcp_by_actor(pred, native, person, "published") == {"actor 1": 95.0, "actor 2": 100.0}
    assert pcp_by_actor(pred, native, person) == {"actor 1": 85.0, "actor 2": 90.0}


# --- the columns of rmpl evaluate's files, on a tiny Shelf-like dataset ----------------


def _tiny_shelf() -> tuple[EvalSet, Poses3D]:
    """Two frames, two actors (ids 1 and 2), two cameras; a result equal to the hand case."""
    K = np.array([[1000.0, 0, 500], [0, 1000, 500], [0, 0, 1]])
    rig = Rig(tuple(Camera(K, np.eye(3), np.array([i, 0, 5.0]), name=str(i)) for i in range(2)))
    gt = np.stack([_gt_shelf() + [0, 0, 0], _gt_shelf() + [2.0, 0, 0]])  # (P, 14, 3)
    gt = np.stack([gt, gt])  # (T, P, 14, 3)
    keypoints = np.zeros((2, 2, 2, 17, 2))  # (T, V, N, 17, 2): not used to score results
    data = MultiViewDataset(
        rig, np.array([0, 1]), gt, "shelf14", keypoints, np.ones((2, 2, 2, 17)), "shelf",
        person_ids=np.array([1, 2]),
    )  # fmt: skip
    evset = EvalSet((data,), "shelf", "2D: none (tiny test set)", "given", pcp=True)
    pred = np.stack([_coco(**BODY), _coco(**BODY) + [2.0, 0, 0]])  # (P, 17, 3)
    pred = np.stack([pred, pred.copy()])  # (T, P, 17, 3)
    pred[1, 0, COCO17.index("right_wrist"), 0] += 1.0  # actor 1, second frame
    return evset, Poses3D(points=pred, frames=np.array([0, 1]))


def _read(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_evaluate_files_carry_the_published_pcp(tmp_path):
    evset, result = _tiny_shelf()
    ev = evaluate_poses(evset, {"run": result})
    write_files(tmp_path, benchmark_files(ev, "rmpl evaluate --dataset shelf"))
    rows = _read(tmp_path / "results.csv")
    cols = list(rows[0])
    # The existing columns keep their positions; the published PCP comes at the end.
    assert cols[-3:] == ["pcp_lit_actor1", "pcp_lit_actor2", "pcp_lit_mean"]
    assert cols[:-3] == [
        *("views", "method", "mpjpe", "coverage", "kpstar", "pa_mpjpe", "pck", "mpjpe_common"),
        *("pcp_actor1", "pcp_actor2", "pcp_mean", "dropout", "calib_noise", "2d_source"),
    ]
    r = rows[0]
    assert (float(r["pcp_actor1"]), float(r["pcp_actor2"])) == (85.0, 90.0)
    assert (float(r["pcp_lit_actor1"]), float(r["pcp_lit_actor2"])) == (95.0, 100.0)
    assert float(r["pcp_lit_mean"]) == 97.5

    people = {p["person"]: p for p in _read(tmp_path / "per_person.csv")}
    a1 = people["actor 1"]
    assert list(a1)[: list(a1).index("calib_noise") + 1][-3:] == ["pcp", "dropout", "calib_noise"]
    assert (float(a1["pcp"]), float(a1["pcp_lit"])) == (85.0, 95.0)
    assert float(a1["pcp_right_lower_arm"]) == 50.0 and float(a1["pcp_lit_right_lower_arm"]) == 50
    assert float(a1["pcp_head"]) == 0.0 and float(a1["pcp_lit_head"]) == 100.0
    assert float(people["actor 2"]["pcp_lit_torso"]) == 100.0
    assert all(f"pcp_lit_{p}" in a1 and f"pcp_{p}" in a1 for p in PCP_PART_NAMES)

    text = (tmp_path / "results.md").read_text()
    assert "coco2shelf3D" in text and "[0.75, 0.75, 1.5]" in text  # the header states it
    assert "PCP mean, published (%)" in text and "PCP actor 1, published (%)" in text
    part_rows = [line for line in text.splitlines() if "| published |" in line]
    assert len(part_rows) == 2  # one per actor
    # actor 1, published: head 100, R upper arm 100, R lower arm 50, ... PCP 95.
    cells = [c.strip() for c in part_rows[0].strip("|").split("|")]
    assert cells[2:5] == ["actor 1", "published", "100.0"] and cells[6] == "50.0"
    assert cells[-1] == "95.0"


def test_pcp_without_ears_counts_head_and_torso_wrong():
    """No ears (2D labels without them): both conversions lose the neck and head top."""
    pred, native, person = _case()
    pred[:, [COCO17.index("left_ear"), COCO17.index("right_ear")]] = np.nan
    for conversion in ("derived", "published"):
        parts = pcp_parts_by_actor(pred, native, person, conversion)["actor 2"]
        assert parts["head"] == parts["torso"] == 0.0
        assert pcp_by_actor(pred, native, person, conversion)["actor 2"] == 80.0
