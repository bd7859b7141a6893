"""The view check on HALPE-26 2D and 3D: it compares the COCO-17 joints, so the feet, neck,
head top and mid-hip change no status, whichever joint set the 3D is in."""

import numpy as np

from rmpl.pipeline.consistency import check_views, person_2d
from rmpl.skeleton import COCO17, HALPE26
from tests.pipeline.test_consistency import (
    A,
    D,
    check,
    make_rig,
    one_per_view,
    two_people,
)


def extras(X: np.ndarray) -> np.ndarray:
    """HALPE-26's nine extra joints of COCO-17 people (..., 17, 3) -> (..., 9, 3)."""
    j = COCO17.index
    mid_sh = 0.5 * (X[..., j("left_shoulder"), :] + X[..., j("right_shoulder"), :])
    mid_hip = 0.5 * (X[..., j("left_hip"), :] + X[..., j("right_hip"), :])
    head = X[..., j("nose"), :] + [0.0, 0.08, 0.15]
    out = [head, mid_sh + [0.0, 0.0, 0.05], mid_hip]
    feet = {}
    for side in ("left", "right"):
        ankle = X[..., j(f"{side}_ankle"), :]
        feet[f"{side}_big_toe"] = ankle + [0.0, -0.15, -0.03]
        feet[f"{side}_small_toe"] = ankle + [0.04 if side == "left" else -0.04, -0.12, -0.03]
        feet[f"{side}_heel"] = ankle + [0.0, 0.06, -0.03]
    out += [feet[n] for n in HALPE26.joints[20:]]
    return np.stack(out, axis=-2)


def _rich_2d(kp, sc, X, rig, sees, wrong_feet=False):
    """COCO-17 2D (T, V, 1, 17, 2) -> HALPE-26, the extras projected from the person each
    view sees (or, with ``wrong_feet``, from the other person)."""
    T, V = kp.shape[:2]
    proj = rig.project(extras(X).reshape(T, -1, 3)).reshape(T, V, 2, 9, 2)
    who = np.clip(sees, 0, 1)
    if wrong_feet:
        who = 1 - who
    ex = np.take_along_axis(proj, who[:, :, None, None, None], 2)  # (T, V, 1, 9, 2)
    ex_sc = np.where(np.isnan(kp[..., :1, 0]), 0.0, 0.8) * np.ones(9)
    ex = np.where(ex_sc[..., None] > 0, ex, np.nan)
    return np.concatenate([kp, ex], axis=-2), np.concatenate([sc, ex_sc], axis=-1)


def _scene():
    rig = make_rig()
    sees = np.zeros((40, 4), int)
    sees[10:30, 3] = 1  # camera c3 shows B in frames 110-129
    X = two_people()
    kp, sc = one_per_view(X, rig, sees)
    return rig, sees, X, kp, sc


def test_halpe26_2d_and_3d_give_the_coco17_statuses():
    rig, sees, X, kp, sc = _scene()
    poses, coco = check(rig, kp, sc, mirror=COCO17.flip_permutation())
    assert (coco.status[10:30, 0, 3] == D).all() and (coco.status[:, 0, :3] == A).all()
    kp26, sc26 = _rich_2d(kp, sc, X, rig, sees)
    k2, s2 = person_2d(kp26, sc26, poses.membership)
    pts26 = np.concatenate([poses.points, extras(poses.points)], axis=-2)  # HALPE-26 3D
    rich = check_views(pts26, k2, s2, rig, mirror=HALPE26.flip_permutation())
    np.testing.assert_array_equal(rich.status, coco.status)
    np.testing.assert_array_equal(rich.error, coco.error)
    np.testing.assert_array_equal(rich.size, coco.size)
    np.testing.assert_array_equal(rich.swapped, coco.swapped)
    # a COCO-17 3D (a COCO-17 model) beside HALPE-26 2D, and the reverse
    mixed = check_views(poses.points, k2, s2, rig, mirror=HALPE26.flip_permutation())
    np.testing.assert_array_equal(mixed.status, coco.status)
    k17, s17 = person_2d(kp, sc, poses.membership)
    reverse = check_views(pts26, k17, s17, rig, mirror=COCO17.flip_permutation())
    np.testing.assert_array_equal(reverse.error, coco.error)


def test_feet_of_another_person_change_nothing():
    """Extras taken from the wrong person in every view do not make any view disagree: only
    COCO-17 is compared."""
    rig, sees, X, kp, sc = _scene()
    poses, coco = check(rig, kp, sc)
    kp26, sc26 = _rich_2d(kp, sc, X, rig, sees, wrong_feet=True)
    k2, s2 = person_2d(kp26, sc26, poses.membership)
    rich = check_views(np.concatenate([poses.points, extras(poses.points)], -2), k2, s2, rig)
    np.testing.assert_array_equal(rich.status, coco.status)
    assert rich.failed.tolist() == coco.failed.tolist()
