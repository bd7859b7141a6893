"""Tests of the duplicate-person rule of rmpl.pipeline.association (one person split into
two clusters that share no view) on synthetic four-camera scenes built here."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.pipeline.association import AssociationConfig, associate, duplicate_people
from rmpl.pipeline.runner import RunConfig, associate_frames
from rmpl.skeleton import COCO17

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
BODY = np.array([_FIGURE[n] for n in COCO17.joints])  # (17, 3), metres


def ring_rig(num_views: int = 4) -> Rig:
    """Cameras at 5 m evenly on a ring (the first at 45 degrees), 2 m high, aimed at the
    room's centre, 1000 x 1000 px."""
    cams = []
    K = np.array([[800.0, 0, 500], [0, 800, 500], [0, 0, 1]])
    for v, a in enumerate(np.deg2rad(45 + 360 * np.arange(num_views) / num_views)):
        eye = np.array([5 * np.cos(a), 5 * np.sin(a), 2.0])
        R, t = look_at(eye, np.array([0.0, 0.0, 1.0]))
        cams.append(Camera(K, R, t, size=(1000, 1000), name=f"cam{v}"))
    return Rig(tuple(cams))


def views_of(rig: Rig, people: list[tuple[np.ndarray, list[int]]], rng, noise: float = 1.0):
    """Per view, the 2D people (P_v, 17, 2) and scores (P_v, 17) of the (body (17, 3), views
    that see it) pairs, with Gaussian pixel noise."""
    kps, scs = [], []
    for v in range(len(rig)):
        here = [rig.cameras[v].project(body) for body, seen in people if v in seen]
        kp = np.array(here).reshape(-1, 17, 2) + rng.normal(0, noise, (len(here), 17, 2))
        kps.append(kp)
        scs.append(np.full(kp.shape[:2], 0.9))
    return kps, scs


def split_person(rng) -> tuple[Rig, list[np.ndarray], list[np.ndarray]]:
    """One person, but views 2 and 3 saw a body 0.2 m aside and higher (a poor detection and a
    mixed one agreeing with each other): two clusters {0, 1} and {2, 3}, with the
    second's views the less consistent."""
    rig = ring_rig()
    body = BODY + [0.2, -0.1, 0.0]
    kps, scs = views_of(rig, [(body, [0, 1])], rng, noise=0.5)
    kp2, sc2 = views_of(rig, [(body + [0.2, 0.0, 0.2], [2, 3])], rng, noise=3.0)
    for v in (2, 3):
        kps[v], scs[v] = kp2[v], sc2[v]
    return rig, kps, scs


def test_split_person_is_found_once():
    rig, kps, scs = split_person(np.random.default_rng(0))
    off = associate(kps, scs, rig, AssociationConfig(duplicate_tolerance=None))
    assert len(off) == 2  # the split the rule is for: two view-disjoint clusters
    assert not ((off.members[0] >= 0) & (off.members[1] >= 0)).any()
    on = associate(kps, scs, rig, AssociationConfig(duplicate_tolerance=0.2))
    assert len(on) == 1
    # equal view counts: the cluster whose views agree better (views 0 and 1) stays
    assert on.members[0].tolist() == [0, 0, -1, -1]


def test_the_person_with_more_views_stays():
    """Three views see the person, two others a body 0.2 m aside and higher (less noisy, so the
    tie-break alone would keep it): the number of views decides first."""
    rig = ring_rig(5)
    rng = np.random.default_rng(1)
    body = BODY + [0.2, -0.1, 0.0]
    kps, scs = views_of(rig, [(body, [0, 1, 2])], rng, noise=3.0)
    kp2, sc2 = views_of(rig, [(body + [0.2, 0.0, 0.2], [3, 4])], rng, noise=0.5)
    for v in (3, 4):
        kps[v], scs[v] = kp2[v], sc2[v]
    off = associate(kps, scs, rig, AssociationConfig(duplicate_tolerance=None))
    assert sorted((off.members >= 0).sum(-1).tolist()) == [2, 3]
    keep = duplicate_people(off, rig, AssociationConfig(duplicate_tolerance=0.2))
    assert (off.members[keep] >= 0).tolist() == [[True, True, True, False, False]]


def test_two_people_side_by_side_are_both_kept():
    """Two people 0.7 m apart, each seen by two other cameras: view-disjoint, but each
    one's 3D lands beside, not on, the other's detections."""
    rig = ring_rig()
    rng = np.random.default_rng(4)
    at = np.array([0.3, -0.2, 0.0])  # off the rig's mirror planes (no epipolar ambiguity)
    left, right = BODY + at, BODY + at + [0.7 * np.cos(0.3), 0.7 * np.sin(0.3), 0.0]
    kps, scs = views_of(rig, [(left, [0, 1]), (right, [2, 3])], rng)
    found = associate(kps, scs, rig, AssociationConfig(duplicate_tolerance=0.2))
    assert sorted(found.members.tolist()) == [[-1, -1, 0, 0], [0, 0, -1, -1]]
    # and with every camera seeing both (the rule never compares people sharing a view)
    kps, scs = views_of(rig, [(left, [0, 1, 2, 3]), (right, [0, 1, 2, 3])], rng)
    assert len(associate(kps, scs, rig, AssociationConfig(duplicate_tolerance=0.2))) == 2


def test_off_switch_and_default_through_the_runner():
    rig, kps, scs = split_person(np.random.default_rng(5))
    P = max(len(k) for k in kps) + 1  # an empty slot: one slot per view skips association
    kp = np.full((1, len(rig), P, 17, 2), np.nan)
    sc = np.zeros((1, len(rig), P, 17))
    for v, (k, s) in enumerate(zip(kps, scs, strict=True)):
        kp[0, v, : len(k)], sc[0, v, : len(s)] = k, s
    off = RunConfig(association=AssociationConfig(duplicate_tolerance=None))
    assert len(associate_frames(kp, sc, rig, off.association)[0]) == 2
    assert len(associate_frames(kp, sc, rig, RunConfig().association)[0]) == 1


@pytest.mark.parametrize("bad", [0.0, -0.2, float("nan"), "0.2"])
def test_bad_tolerance_is_refused(bad):
    with pytest.raises(ValueError, match="duplicate_tolerance"):
        AssociationConfig(duplicate_tolerance=bad)
