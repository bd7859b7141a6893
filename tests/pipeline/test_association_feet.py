"""Association carries a detector's feet, neck and mid-hip through, grouping as on COCO-17."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.geometry.triangulate import triangulate
from rmpl.pipeline.association import associate, associate_candidates, group_people, match_poses
from rmpl.skeleton import BODY25, HALPE26
from tests.pipeline.test_association import (
    body25_people,
    observe,
    random_people,
    random_rig,
    synthetic_candidates,
)


def _with_extras(rng, kps, scs):
    """COCO-17 people per view -> HALPE-26 ones whose nine extra joints are random pixels
    (misleading on purpose: they must not change any grouping)."""
    out_kp, out_sc = [], []
    for kp, sc in zip(kps, scs, strict=True):
        extra = rng.uniform(0, 1000, (len(kp), 9, 2))
        out_kp.append(np.concatenate([kp, extra], axis=1))
        out_sc.append(np.concatenate([sc, rng.uniform(0.5, 1.0, (len(kp), 9))], axis=1))
    return out_kp, out_sc


def test_associate_groups_halpe26_as_its_coco17_joints():
    rng = np.random.default_rng(20)
    for _ in range(10):
        num_people, num_views = int(rng.integers(2, 6)), int(rng.integers(3, 6))
        people = random_people(rng, num_people)
        rig = random_rig(rng, num_views)
        kps, scs, _ = observe(rng, people, rig)
        coco = associate(kps, scs, rig)
        kp26, sc26 = _with_extras(rng, kps, scs)
        rich = associate(kp26, sc26, rig)  # 26 joints: HALPE-26 inferred
        np.testing.assert_array_equal(rich.members, coco.members)
        np.testing.assert_array_equal(rich.keypoints[..., :17, :], coco.keypoints)
        np.testing.assert_array_equal(rich.scores[..., :17], coco.scores)
        # every extra joint is carried through, each with its own 2D person
        for n, members in enumerate(rich.members):
            for v, m in enumerate(members):
                if m >= 0:
                    np.testing.assert_array_equal(rich.keypoints[n, v, 17:], kp26[v][m, 17:])


def test_associate_uses_all_joints_of_a_set_without_coco17():
    """Joint sets that do not hold COCO-17 are grouped on every joint, as before."""
    rng = np.random.default_rng(21)
    people = random_people(rng, 3)
    rig = random_rig(rng, 4)
    kps, scs, _ = observe(rng, people, rig)
    a = associate([k[:, :12] for k in kps], [s[:, :12] for s in scs], rig)
    assert a.keypoints.shape[-2] == 12 and len(a) == 3


def test_associate_skeleton_must_match():
    rng = np.random.default_rng(22)
    rig = random_rig(rng, 2)
    kps, scs, _ = observe(rng, random_people(rng, 2), rig)
    with pytest.raises(InputError, match="skeleton"):
        associate(kps, scs, rig, skeleton="halpe26")


def test_group_people_keeps_body25_feet_neck_mid_hip():
    rng = np.random.default_rng(23)
    rig = random_rig(rng, 1)
    people = body25_people(random_people(rng, 3))
    pixels = rig.project(people)[:, 0]  # (P, 25, 2)
    cands, _ = synthetic_candidates(rng, pixels)
    kp, sc = group_people(cands, output="auto")
    native, native_sc = group_people(cands, output=None)
    assert kp.shape == (3, 26, 2) and sc.shape == (3, 26)
    for j, name in enumerate(HALPE26.joints):
        if name == "head_top":  # BODY_25 has none
            assert np.isnan(kp[:, j]).all() and (sc[:, j] == 0).all()
        else:
            np.testing.assert_array_equal(kp[:, j], native[:, BODY25.index(name)])
            np.testing.assert_array_equal(sc[:, j], native_sc[:, BODY25.index(name)])
    coco, _ = group_people(cands, output="coco17")
    np.testing.assert_array_equal(coco, kp[:, :17])


def test_associate_candidates_carries_feet_to_triangulation():
    rng = np.random.default_rng(24)
    people = body25_people(random_people(rng, 3))  # (3, 25, 3)
    rig = random_rig(rng, 4)
    pixels = rig.project(people)
    cands = [synthetic_candidates(rng, pixels[:, v])[0] for v in range(4)]
    coco = associate_candidates(cands, rig, output="coco17")
    rich = associate_candidates(cands, rig, output="auto")
    assert rich.keypoints.shape == (3, 4, 26, 2)
    np.testing.assert_array_equal(rich.members, coco.members)
    points = triangulate(rich.keypoints, rich.scores, rig).points  # (3, 26, 3)
    truth = np.full((3, 26, 3), np.nan)
    for j, name in enumerate(HALPE26.joints):
        if name in BODY25.joints:
            truth[:, j] = people[:, BODY25.index(name)]
    match = match_poses(points, truth)
    assert sorted(match.tolist()) == [0, 1, 2]
    heels = HALPE26.indices(["left_heel", "right_heel", "left_big_toe", "right_small_toe"])
    assert np.abs(points[match][:, heels] - truth[:, heels]).max() < 1e-6
    assert np.isnan(points[:, HALPE26.index("head_top")]).all()
