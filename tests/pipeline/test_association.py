"""Tests of rmpl.pipeline.association on synthetic multi-person scenes built here."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.geometry.triangulate import triangulate
from rmpl.pipeline.association import (
    BODY25_LIMBS,
    Association,
    AssociationConfig,
    Candidates,
    GroupingConfig,
    associate,
    associate_candidates,
    cluster_people,
    group_people,
    match_poses,
    ray_distance_cost,
)
from rmpl.skeleton import BODY25, COCO17

# A standing stick figure in COCO-17 order, body frame (x = its left, y = forward, z up).
_FIGURE = {
    "nose": (0.0, 0.10, 1.60),
    "left_eye": (0.03, 0.08, 1.63),
    "right_eye": (-0.03, 0.08, 1.63),
    "left_ear": (0.08, 0.0, 1.60),
    "right_ear": (-0.08, 0.0, 1.60),
    "left_shoulder": (0.18, 0.0, 1.42),
    "right_shoulder": (-0.18, 0.0, 1.42),
    "left_elbow": (0.22, 0.0, 1.12),
    "right_elbow": (-0.22, 0.0, 1.12),
    "left_wrist": (0.24, 0.05, 0.85),
    "right_wrist": (-0.24, 0.05, 0.85),
    "left_hip": (0.10, 0.0, 0.92),
    "right_hip": (-0.10, 0.0, 0.92),
    "left_knee": (0.10, 0.02, 0.50),
    "right_knee": (-0.10, 0.02, 0.50),
    "left_ankle": (0.10, 0.0, 0.08),
    "right_ankle": (-0.10, 0.0, 0.08),
}
TEMPLATE = np.array([_FIGURE[n] for n in COCO17.joints])  # (17, 3), metres


def random_people(rng: np.random.Generator, num: int, min_gap: float = 0.8) -> np.ndarray:
    """``num`` stick figures in a 4 x 4 m room, feet at least ``min_gap`` apart: (num, 17, 3)."""
    places: list[np.ndarray] = []
    while len(places) < num:
        p = rng.uniform(-2, 2, size=2)
        if all(np.linalg.norm(p - q) >= min_gap for q in places):
            places.append(p)
    people = []
    for p in places:
        yaw = rng.uniform(-np.pi, np.pi)
        Rz = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
        body = TEMPLATE * rng.uniform(0.9, 1.1) + rng.normal(0, 0.02, TEMPLATE.shape)
        people.append(body @ Rz.T + [p[0], p[1], 0.0])
    return np.array(people)


def random_rig(rng: np.random.Generator, num_views: int) -> Rig:
    """Cameras on a ring around the room, aimed at its centre, 1000 x 1000 px images."""
    cams = []
    angles = np.sort(rng.uniform(0, 2 * np.pi, num_views))
    for v, a in enumerate(angles):
        r = rng.uniform(5, 7)
        eye = np.array([r * np.cos(a), r * np.sin(a), rng.uniform(1.5, 3.0)])
        R, t = look_at(eye, np.array([*rng.uniform(-0.5, 0.5, 2), 1.0]))
        f = rng.uniform(700, 900)
        K = np.array([[f, 0, 500], [0, f, 500], [0, 0, 1]])
        cams.append(Camera(K, R, t, size=(1000, 1000), name=str(v)))
    return Rig(tuple(cams))


def observe(rng, people, rig, drop=0.3, noise=2.0, missing=0.1):
    """Per-view shuffled 2D people with noise, missing joints and people unseen in views.

    Returns:
        keypoints and scores per view, and the true person id of each 2D person.
    """
    P, V, J = len(people), len(rig), people.shape[1]
    seen = rng.random((P, V)) >= drop
    for p in range(P):  # every person in at least two views
        while seen[p].sum() < 2:
            seen[p, rng.integers(V)] = True
    proj = rig.project(people)  # (P, V, J, 2)
    kps, scs, ids = [], [], []
    for v in range(V):
        who = rng.permutation(np.flatnonzero(seen[:, v]))
        kp = proj[who, v] + rng.normal(0, noise, (len(who), J, 2))
        sc = rng.uniform(0.5, 1.0, (len(who), J))
        gone = rng.random((len(who), J)) < missing
        kp[gone], sc[gone] = np.nan, 0.0
        kps.append(kp)
        scs.append(sc)
        ids.append(who)
    return kps, scs, ids


def count_errors(result: Association, ids: list[np.ndarray], num_people: int) -> int:
    """True people not recovered as exactly one pure cluster holding all their views."""
    clusters = []
    for members in result.members:
        clusters.append({(v, int(ids[v][m])) for v, m in enumerate(members) if m >= 0})
    errors = 0
    for p in range(num_people):
        truth = {(v, p) for v in range(len(ids)) if p in ids[v]}
        errors += sum(c == truth for c in clusters) != 1
    return errors


def test_associate_recovers_synthetic_people():
    rng = np.random.default_rng(0)
    errors, total = 0, 0
    for _ in range(20):
        num_people, num_views = int(rng.integers(2, 6)), int(rng.integers(3, 6))
        people, rig = random_people(rng, num_people), random_rig(rng, num_views)
        kps, scs, ids = observe(rng, people, rig)
        result = associate(kps, scs, rig)
        errors += count_errors(result, ids, num_people)
        total += num_people
    assert total > 50
    assert errors <= 1, f"{errors} of {total} people not recovered"


def test_associate_two_views():
    rng = np.random.default_rng(1)
    errors, total = 0, 0
    for _ in range(20):
        num_people = int(rng.integers(2, 5))
        people, rig = random_people(rng, num_people), random_rig(rng, 2)
        kps, scs, ids = observe(rng, people, rig, drop=0.0)
        errors += count_errors(associate(kps, scs, rig), ids, num_people)
        total += num_people
    assert errors <= 2, f"{errors} of {total} people not recovered"


def test_association_output_is_the_triangulation_input():
    rng = np.random.default_rng(2)
    people, rig = random_people(rng, 3), random_rig(rng, 4)
    kps, scs, ids = observe(rng, people, rig, noise=0.5)
    result = associate(kps, scs, rig)
    assert result.keypoints.shape == (3, 4, 17, 2) and result.scores.shape == (3, 4, 17)
    unseen = result.members < 0
    assert np.isnan(result.keypoints[unseen]).all() and (result.scores[unseen] == 0).all()
    assert ((result.scores > 0) == np.isfinite(result.keypoints).all(-1)).all()
    points = triangulate(result.keypoints, result.scores, rig).points  # (3, 17, 3)
    match = match_poses(points, people)
    assert sorted(match.tolist()) == [0, 1, 2]
    err = np.linalg.norm(points[match] - people, axis=-1)
    assert np.nanmedian(err) < 0.02


def test_person_seen_once_is_dropped_unless_asked():
    rng = np.random.default_rng(3)
    people, rig = random_people(rng, 2), random_rig(rng, 3)
    proj = rig.project(people)  # (2, 3, 17, 2)
    kps = [proj[:, 0], proj[:1, 1], proj[:1, 2]]  # person 1 only in view 0
    scs = [np.ones(k.shape[:2]) for k in kps]
    assert len(associate(kps, scs, rig)) == 1
    once = associate(kps, scs, rig, AssociationConfig(min_views=1))
    assert len(once) == 2 and (once.members >= 0).sum(-1).tolist() == [3, 1]


def test_associate_handles_empty_views():
    rng = np.random.default_rng(4)
    rig = random_rig(rng, 3)
    empty = [np.zeros((0, 17, 2))] * 3
    result = associate(empty, [np.zeros((0, 17))] * 3, rig)
    assert result.keypoints.shape == (0, 3, 17, 2)


def test_associate_rejects_bad_input():
    rig = random_rig(np.random.default_rng(5), 3)
    kp, sc = np.zeros((1, 17, 2)), np.ones((1, 17))
    with pytest.raises(InputError, match="one entry per camera"):
        associate([kp, kp], [sc, sc], rig)
    with pytest.raises(InputError, match=r"scores\[1\]"):
        associate([kp, kp, kp], [sc, np.ones((2, 17)), sc], rig)


def test_ray_distance_cost_is_zero_for_the_same_point_and_nan_in_a_view():
    rig = random_rig(np.random.default_rng(6), 2)
    X = TEMPLATE + [0.3, -0.2, 0.0]
    kp = rig.project(X)  # (2, 17, 2)
    cost = ray_distance_cost(kp, np.ones((2, 17)), np.array([0, 1]), rig)
    assert cost[0, 1] == pytest.approx(0.0, abs=1e-6) and np.isnan(cost[0, 0])
    far = rig.project(X + [1.0, 0.0, 0.0])[1]
    cost = ray_distance_cost(np.stack([kp[0], far]), np.ones((2, 17)), np.array([0, 1]), rig)
    assert cost[0, 1] > 0.2
    few = np.zeros((2, 17))
    few[:, :2] = 1.0  # two common joints < min_common_joints
    assert np.isnan(ray_distance_cost(kp, few, np.array([0, 1]), rig)[0, 1])


def test_cluster_people_never_joins_two_people_of_one_view():
    cost = np.full((3, 3), 0.01)
    labels = cluster_people(cost, np.array([0, 0, 1]), max_cost=0.1)
    assert labels[0] != labels[1] and len(set(labels.tolist())) == 2


def body25_people(people: np.ndarray) -> np.ndarray:
    """BODY_25 joints of COCO-17 stick figures: neck and mid-hip as midpoints, feet added."""
    P = len(people)
    out = np.zeros((P, 25, 3))
    for i, name in enumerate(COCO17.joints):
        out[:, BODY25.index(name)] = people[:, i]
    out[:, BODY25.index("neck")] = people[:, [5, 6]].mean(1)
    out[:, BODY25.index("mid_hip")] = people[:, [11, 12]].mean(1)
    for side in ("left", "right"):
        ankle = out[:, BODY25.index(f"{side}_ankle")]
        for k, part in enumerate(("big_toe", "small_toe", "heel")):
            out[:, BODY25.index(f"{side}_{part}")] = ankle + [0.0, 0.15 - 0.1 * k, -0.07]
    return out


def synthetic_candidates(rng, pixels: np.ndarray, distractor: bool = False):
    """Shuffled BODY_25 candidates of people (P, 25, 2) with affinities: high within a
    person, low and partly above threshold across people."""
    P = len(pixels)
    order = [rng.permutation(P) for _ in range(25)]  # candidate k of joint j: person order[j][k]
    points = [np.column_stack([pixels[o, j], rng.uniform(0.5, 1, P)]) for j, o in enumerate(order)]
    affinities = []
    for a, b in BODY25_LIMBS:
        same = order[a][:, None] == order[b][None, :]
        low, high = rng.uniform(0, 0.3, (P, P)), rng.uniform(0.5, 0.9, (P, P))
        affinities.append(np.where(same, high, low))
    if distractor:  # a confident stray right wrist, weakly linked to every right elbow
        j = BODY25.index("right_wrist")
        points[j] = np.vstack([points[j], [5.0, 5.0, 0.95]])
        k = BODY25_LIMBS.index((3, 4))
        affinities[k] = np.hstack([affinities[k], np.full((P, 1), 0.35)])
    return Candidates(tuple(points), tuple(affinities)), order


def test_group_people_recovers_synthetic_people():
    rng = np.random.default_rng(7)
    rig = random_rig(rng, 1)
    for _ in range(5):
        people = body25_people(random_people(rng, int(rng.integers(2, 6))))
        pixels = rig.project(people)[:, 0]  # (P, 25, 2)
        cands, _ = synthetic_candidates(rng, pixels, distractor=True)
        kp, sc = group_people(cands, output=None)
        assert kp.shape == (len(people), 25, 2)
        for person in kp:
            dist = np.abs(pixels - person).max(axis=(1, 2))
            assert dist.min() < 1e-9, "a grouped person mixes candidates of several people"
        assert (sc > 0).all()


def test_group_people_converts_to_coco17_and_drops_small_people():
    rng = np.random.default_rng(8)
    rig = random_rig(rng, 1)
    people = body25_people(random_people(rng, 2))
    pixels = rig.project(people)[:, 0]
    cands, _ = synthetic_candidates(rng, pixels)
    kp, sc = group_people(cands)  # COCO-17
    assert kp.shape == (2, 17, 2) and sc.shape == (2, 17)
    coco_idx = [BODY25.index(n) for n in COCO17.joints]
    for person in kp:
        assert np.abs(pixels[:, coco_idx] - person).max(axis=(1, 2)).min() < 1e-9
    # Keep only the neck - mid-hip limb: two-joint people fall below min_parts.
    aff = [
        A if (a, b) == (1, 8) else np.zeros_like(A)
        for (a, b), A in zip(BODY25_LIMBS, cands.affinities, strict=True)
    ]
    weak = Candidates(cands.points, tuple(aff))
    assert len(group_people(weak, output=None)[0]) == 0
    assert len(group_people(weak, GroupingConfig(min_parts=2), output=None)[0]) == 2


def test_group_people_missing_joints_are_nan_with_zero_score():
    rng = np.random.default_rng(9)
    pixels = random_rig(rng, 1).project(body25_people(random_people(rng, 1)))[:, 0]
    cands, _ = synthetic_candidates(rng, pixels)
    points = list(cands.points)
    aff = list(cands.affinities)
    wrist = BODY25.index("left_wrist")
    points[wrist] = np.zeros((0, 3))
    for k, (a, b) in enumerate(BODY25_LIMBS):
        if wrist in (a, b):
            aff[k] = np.zeros((len(points[a]), len(points[b])))
    kp, sc = group_people(Candidates(tuple(points), tuple(aff)), output=None)
    assert np.isnan(kp[0, wrist]).all() and sc[0, wrist] == 0


def test_candidates_reject_bad_affinity_shapes():
    points = tuple(np.zeros((1, 3)) for _ in range(25))
    aff = [np.zeros((1, 1)) for _ in BODY25_LIMBS]
    aff[3] = np.zeros((2, 1))
    with pytest.raises(ValueError, match=r"limb \(8, 9\)"):
        Candidates(points, tuple(aff))


def test_associate_candidates_end_to_end():
    rng = np.random.default_rng(10)
    people = random_people(rng, 3)
    rig = random_rig(rng, 4)
    pixels = rig.project(body25_people(people))  # (3, 4, 25, 2)
    cands = [synthetic_candidates(rng, pixels[:, v])[0] for v in range(4)]
    result = associate_candidates(cands, rig)
    assert result.keypoints.shape == (3, 4, 17, 2)
    points = triangulate(result.keypoints, result.scores, rig).points
    match = match_poses(points, people)
    assert sorted(match.tolist()) == [0, 1, 2]
    assert np.abs(points[match] - people).max() < 1e-6


def test_match_poses_gates_and_skips_absent_people():
    rng = np.random.default_rng(11)
    gt = random_people(rng, 3)
    gt[1] = np.nan  # absent
    pred = np.stack([gt[2] + 0.03, gt[0] - 0.02, gt[0] + 2.0])
    assert match_poses(pred, gt).tolist() == [1, -1, 0]
    assert match_poses(pred, gt, max_distance=0.01).tolist() == [-1, -1, -1]
    assert match_poses(pred[:0], gt).tolist() == [-1, -1, -1]
