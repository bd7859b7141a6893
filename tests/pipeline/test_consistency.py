"""The view check: a view that sees another person is flagged with its person and frames, a
blend fails, a clean scene passes; missed, out of view and unchecked are told apart."""

import numpy as np
import pytest

from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.poses import ViewStatus
from rmpl.pipeline.consistency import (
    EXIT_VIEWS_DISAGREE,
    ConsistencyConfig,
    check_views,
    format_ranges,
    frame_ranges,
    person_2d,
)
from rmpl.pipeline.runner import RunConfig, run
from rmpl.skeleton import COCO17

A, D, M, O, U = (ViewStatus.AGREES, ViewStatus.DISAGREES, ViewStatus.MISSED,
                 ViewStatus.OUT_OF_VIEW, ViewStatus.UNCHECKED)  # fmt: skip
FRAMES = np.arange(100, 140)  # frame numbers of the 40 frames


def make_rig(views=4, focal=1000.0, away=False) -> Rig:
    """``views`` cameras on a 5 m circle looking at the middle of the room; with ``away`` a
    last camera looks out of the room (it never sees anybody)."""
    K = np.array([[focal, 0, 640], [0, focal, 480], [0, 0, 1]])
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views + 0.4
        eye = np.array([5 * np.cos(a), 5 * np.sin(a), 2.5])
        cams.append(Camera(K, *look_at(eye, np.array([0.0, 0, 1])), size=(1280, 960), name=f"c{v}"))
    if away:
        eye = np.array([0.0, 5.0, 2.5])
        cams.append(Camera(K, *look_at(eye, np.array([0.0, 9, 1])), size=(1280, 960), name="out"))
    return Rig(tuple(cams))


def standing(height: float) -> np.ndarray:
    """A COCO-17 person (17, 3) standing at the origin facing -y, at the landmark heights of
    Drillis & Contini's proportions."""
    H = height
    z = {"nose": 0.93, "eye": 0.936, "ear": 0.92, "sh": 0.818, "el": 0.63, "wr": 0.485,
         "hip": 0.53, "knee": 0.285, "ank": 0.039}  # fmt: skip
    x = {"eye": 0.03, "ear": 0.07, "sh": 0.13, "el": 0.16, "wr": 0.17, "hip": 0.09,
         "knee": 0.09, "ank": 0.09}  # fmt: skip
    pts = [[0, -0.1 * H, z["nose"] * H]]
    for part in ("eye", "ear", "sh", "el", "wr", "hip", "knee", "ank"):
        for side in (1, -1):  # left (+x), right
            pts.append([side * x[part] * H, -0.02 * H if part == "eye" else 0.0, z[part] * H])
    return np.array(pts)


def two_people(T=40, seed=0):
    """Two people, 1.2 m apart, walking: A (1.80 m) and B (1.60 m), (T, 2, 17, 3)."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 1, T)[:, None]
    A_pos = np.concatenate([-0.6 + 0.8 * s, 0.2 + 0 * s, 0 * s], 1)
    B_pos = np.concatenate([0.6 + 0 * s, -0.3 - 0.8 * s, 0 * s], 1)
    X = np.stack([standing(1.8)[None] + A_pos[:, None], standing(1.6)[None] + B_pos[:, None]], 1)
    return X + rng.normal(0, 0.005, X.shape)


def one_per_view(X, rig, sees, seed=0):
    """A single-person detector: view v shows person ``sees[t, v]`` (-1: nobody);
    returns keypoints (T, V, 1, J, 2) with 1 px noise and scores (T, V, 1, J)."""
    rng = np.random.default_rng(seed)
    T = len(X)
    proj = rig.project(X.reshape(T, -1, 3)).reshape(T, len(rig), 2, 17, 2)
    idx = np.clip(sees, 0, 1)
    kp = np.take_along_axis(proj, idx[:, :, None, None, None], 2)[:, :, 0]
    kp = kp + rng.normal(0, 1.0, kp.shape)
    sc = np.full(kp.shape[:-1], 0.9)
    kp[sees < 0], sc[sees < 0] = np.nan, 0
    return kp[:, :, None], sc[:, :, None]


def check(rig, kp, sc, config=None, mirror=None):
    """The run (triangulation, as fast as it gets) and the check of its tracks."""
    poses = run(kp, sc, rig, frames=FRAMES, fps=25.0, config=RunConfig(method="triangulate"),
                progress=False)  # fmt: skip
    k2, s2 = person_2d(kp, sc, poses.membership)
    return poses, check_views(poses.points, k2, s2, rig, config=config, mirror=mirror)


def test_a_view_that_sees_the_other_person_is_flagged_with_its_frames():
    rig = make_rig()
    sees = np.zeros((40, 4), int)
    sees[10:30, 3] = 1  # camera c3 shows B in frames 110-129; the others show A
    poses, c = check(rig, *one_per_view(two_people(), rig, sees))
    assert poses.num_people == 1  # one person per view: rmpl made one (blended) person
    assert (c.status[10:30, 0, 3] == D).all()
    assert (np.delete(c.status[:, 0, 3], range(10, 30)) == A).all()
    assert (c.status[:, 0, :3] == A).all()
    [d] = c.disagreements(poses.frames)
    assert (d.person, d.view, d.ranges, d.frames) == (0, 3, ((110, 129),), 20)
    assert d.median_error > 0.2  # the other person stands 1.2 m away: 0.6+ of a height
    # 20 of 40 frames contested: not most of them, so the run does not fail.
    assert c.contested[:, 0].sum() == 20 and not c.failed.any() and c.exit_code == 0


def test_a_left_right_swap_is_told_from_another_person():
    """Camera c3 (in front of A) swaps A's sides in frames 105-109; camera c2 shows B in
    frames 120-129. Both disagree; only the first is a left/right swap."""
    rig = make_rig()
    sees = np.zeros((40, 4), int)
    sees[20:30, 2] = 1
    X = two_people()
    # A does jumping jacks: arms and legs spread, so that swapping its sides moves most
    # joints far (standing straight, a swap moves the median joint by less than 0.2).
    for joint, dx in ((7, 0.3), (9, 0.45), (13, 0.2), (15, 0.3)):  # elbow, wrist, knee, ankle
        X[:, 0, joint, 0] += dx * 1.8
        X[:, 0, joint + 1, 0] -= dx * 1.8
    X[:, 0, 7:11, 2] = X[:, 0, 5:7, 2].mean(-1, keepdims=True)  # hands at shoulder height
    kp, sc = one_per_view(X, rig, sees)
    kp[5:10, 3, 0] = kp[5:10, 3, 0][:, COCO17.flip_permutation()]
    poses, c = check(rig, kp, sc, mirror=COCO17.flip_permutation())
    assert (c.status[5:10, 0, 3] == D).all() and c.swapped[5:10, 0, 3].all()
    assert (c.status[20:30, 0, 2] == D).all() and not c.swapped[20:30, 0, 2].any()
    assert c.swapped.sum() == 5
    by_view = {d.view: d for d in c.disagreements(poses.frames)}
    assert (by_view[3].ranges, by_view[3].swapped) == (((105, 109),), 5)
    assert (by_view[2].ranges, by_view[2].swapped) == (((120, 129),), 0)
    assert check(rig, kp, sc)[1].swapped.sum() == 0  # no mirror given: not told


def test_a_clean_scene_is_not_flagged():
    rig = make_rig()
    poses, c = check(rig, *one_per_view(two_people(), rig, np.zeros((40, 4), int)))
    assert (c.status == A).all()
    assert c.disagreements(poses.frames) == [] and c.exit_code == 0
    assert np.nanmax(c.error) < 0.05  # 1 px of noise on a 300+ px tall person


def test_a_blend_in_most_frames_fails():
    rig = make_rig()
    sees = np.zeros((40, 4), int)
    sees[:25, 3] = 1  # 25 of 40 frames: c3 sees B
    poses, c = check(rig, *one_per_view(two_people(), rig, sees))
    assert c.failed.tolist() == [True] and c.exit_code == EXIT_VIEWS_DISAGREE == 3


def test_two_cameras_on_each_person_fail_in_every_frame():
    """Two cameras see A, two see B: no view is the odd one out, every frame is contested."""
    rig = make_rig()
    sees = np.zeros((40, 4), int)
    sees[:, 2:] = 1
    poses, c = check(rig, *one_per_view(two_people(), rig, sees))
    disagree = (c.status[:, 0] == D).sum(-1)
    assert np.median(disagree) == 2 and (disagree >= 1).all()  # the pair found is either
    assert c.contested.all() and c.failed.all()


def test_two_cameras_that_disagree_both_disagree():
    """Two cameras on opposite sides: their rays of different people meet behind a camera
    or nowhere near; neither can be the odd one out, so both disagree."""
    rig = make_rig(views=2)
    sees = np.array([[0, 1]] * 40)
    poses, c = check(rig, *one_per_view(two_people(), rig, sees))
    assert (c.status[:, 0] == D).all() and c.failed.all()


def test_missed_out_of_view_and_unchecked_are_told_apart():
    rig = make_rig(views=4, away=True)
    sees = np.zeros((40, 5), int)
    sees[:, 4] = -1  # the camera looking out of the room never sees anybody
    sees[5:8, 1] = -1  # c1 misses the person in frames 105-107
    kp, sc = one_per_view(two_people(), rig, sees)
    sc[3, 2, 0, 3:] = 0  # c2 sees 3 joints in frame 103: too few to compare
    kp[3, 2, 0, 3:] = np.nan
    poses, c = check(rig, kp, sc)
    assert (c.status[:, 0, 4] == O).all()
    assert (c.status[5:8, 0, 1] == M).all()
    assert c.status[3, 0, 2] == U
    ok = np.ones((40, 5), bool)
    ok[:, 4], ok[5:8, 1], ok[3, 2] = False, False, False
    assert (c.status[:, 0][ok] == A).all()


def test_the_threshold_is_relative_to_the_persons_size():
    """Twice the focal length doubles every pixel error and the person's size: the
    fractions and the statuses stay."""
    sees = np.zeros((40, 4), int)
    sees[10:30, 3] = 1
    X = two_people()
    out = []
    for focal in (1000.0, 2000.0):
        rig = make_rig(focal=focal)
        kp, sc = one_per_view(X, rig, sees)
        kp = rig.project(X[:, 0])[:, :, None]  # no noise, so that the two agree exactly
        kp[10:30, 3, 0] = rig.project(X[10:30, 1])[:, 3]
        out.append(check(rig, kp, sc)[1])
    np.testing.assert_array_equal(out[0].status, out[1].status)
    np.testing.assert_allclose(out[0].error, out[1].error, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(out[1].size, 2 * out[0].size, rtol=1e-9)


def test_the_persons_height_sets_its_size():
    rig = make_rig()
    X = two_people()
    kp, sc = one_per_view(X, rig, np.zeros((40, 4), int))
    poses, c = check(rig, kp, sc)
    k2, s2 = person_2d(kp, sc, poses.membership)
    tall = check_views(poses.points, k2, s2, rig, heights=np.array([3.4]))
    np.testing.assert_allclose(tall.size, 2 * c.size, rtol=1e-9)  # 1.70 m by default


def test_person_2d_follows_the_membership():
    T, V, N, J = 2, 3, 2, 17
    kp = np.arange(T * V * N * J * 2, dtype=float).reshape(T, V, N, J, 2)
    sc = np.ones((T, V, N, J))
    m = np.array([[[1, 0, -1]], [[0, -1, 1]]])  # (T, P=1, V)
    k2, s2 = person_2d(kp, sc, m)
    assert k2.shape == (T, 1, V, J, 2)
    np.testing.assert_array_equal(k2[0, 0, 0], kp[0, 0, 1])
    np.testing.assert_array_equal(k2[1, 0, 2], kp[1, 2, 1])
    assert np.isnan(k2[0, 0, 2]).all() and (s2[0, 0, 2] == 0).all() and (s2[1, 0, 1] == 0).all()


def test_frame_ranges_and_settings():
    assert frame_ranges(np.arange(5), np.zeros(5, bool)) == []
    assert frame_ranges(np.array([3, 7, 8]), np.ones(3, bool)) == [(3, 8)]
    assert format_ranges([(1, 1)] * 8, limit=2) == "1, 1 (+6 more)"
    for bad in ({"threshold": 0}, {"min_joints": 0}, {"most_frames": 1.5}):
        with pytest.raises(ValueError):
            ConsistencyConfig(**bad)


def test_a_view_with_too_few_joints_is_not_counted_as_disagreeing():
    """Two cameras that disagree and a third with 3 joints: the third stays unchecked."""
    rig = make_rig(views=3)
    sees = np.array([[0, 1, 0]] * 40)
    kp, sc = one_per_view(two_people(), rig, sees)
    sc[:, 2, 0, 3:] = 0  # c2 sees 3 joints: too few to compare
    kp[:, 2, 0, 3:] = np.nan
    poses, c = check(rig, kp, sc)
    assert (c.status[:, 0, 2] == U).all()
