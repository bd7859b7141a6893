"""Height from bone lengths: skeletons of known height, missing joints, too little data,
and anny bodies whose mesh gives the true height."""

import numpy as np
import pytest

from rmpl.anthropometry import CHAIN_FRACTION, bone_lengths, estimate_height
from rmpl.errors import InputError
from tests.conftest import synth_ready

# COCO-17 indices
L_SH, R_SH, L_HIP, R_HIP, L_KNEE, R_KNEE, L_ANK, R_ANK = 5, 6, 11, 12, 13, 14, 15, 16


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [k for k in range(3) if k != axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def walker(height: float, T: int = 40, seed: int = 0) -> np.ndarray:
    """A COCO-17 track (T, 17, 3) whose shank, thigh and trunk follow Drillis & Contini's
    proportions of ``height``, moving: hips and knees flex, the trunk leans and turns, the
    person walks. Joints the height does not use are filled with plausible positions."""
    rng = np.random.default_rng(seed)
    shank, thigh, trunk = 0.246 * height, 0.245 * height, 0.288 * height
    pts = np.full((T, 17, 3), np.nan)
    down = np.array([0.0, 0.0, -1.0])
    for t in range(T):
        turn = _rot(2, rng.uniform(-np.pi, np.pi))
        pelvis = np.array([0.05 * t, 0.0, 0.5 * height])
        for side, hip, knee, ankle in ((1, L_HIP, L_KNEE, L_ANK), (-1, R_HIP, R_KNEE, R_ANK)):
            h = pelvis + turn @ [side * 0.09 * height, 0, 0]
            thigh_dir = turn @ _rot(0, rng.uniform(-0.6, 1.2)) @ down
            k = h + thigh * thigh_dir
            shank_dir = turn @ _rot(0, rng.uniform(-1.5, 0.0)) @ _rot(0, 0.3) @ down
            pts[t, hip], pts[t, knee], pts[t, ankle] = h, k, k + shank * shank_dir
        lean = turn @ _rot(0, rng.uniform(-0.2, 0.6)) @ _rot(1, rng.uniform(-0.2, 0.2))
        neck = pelvis + trunk * (lean @ [0, 0, 1.0])
        for side, sh in ((1, L_SH), (-1, R_SH)):
            pts[t, sh] = neck + lean @ [side * 0.13 * height, 0, 0]
        pts[t, :5] = neck + lean @ [0, 0, 0.1 * height]  # the head
        pts[t, 7:11] = pts[t, [L_SH, R_SH, L_SH, R_SH]] - [0, 0, 0.25 * height]
    return pts


@pytest.mark.parametrize("height", [1.2, 1.62, 1.95])
def test_known_height_in_any_pose(height):
    assert estimate_height(walker(height)) == pytest.approx(height, rel=1e-9)


def test_noise_outliers_and_missing_joints():
    H = 1.75
    rng = np.random.default_rng(1)
    pts = walker(H, T=60) + rng.normal(0, 0.01, (60, 17, 3))  # 1 cm detector noise
    pts[::7] += rng.normal(0, 0.3, pts[::7].shape)  # one frame in seven is garbage
    pts[rng.random((60, 17)) < 0.2] = np.nan  # a fifth of the joints missing
    assert estimate_height(pts) == pytest.approx(H, rel=0.02)


def test_one_side_suffices():
    H = 1.68
    pts = walker(H)
    pts[:, [R_KNEE, R_ANK]] = np.nan  # the right leg is never seen whole
    assert estimate_height(pts) == pytest.approx(H, rel=1e-9)
    assert np.isnan(bone_lengths(pts)["right_shank"][0])
    assert bone_lengths(pts)["right_shank"][1] == 0


def test_bones_shorter_than_the_proportions_give_a_shorter_person():
    pts = walker(1.8)
    pts[:, :, :] *= 0.5  # every length halves
    assert estimate_height(pts) == pytest.approx(0.9, rel=1e-9)
    assert CHAIN_FRACTION == pytest.approx(0.779)


@pytest.mark.parametrize(
    "hide, frames",
    [((L_SH, R_SH), 40), ((L_KNEE, R_KNEE), 40), ((L_ANK, R_ANK), 40), ((), 4)],
)
def test_too_little_data_is_refused(hide, frames):
    pts = walker(1.7)[:frames]
    pts[:, list(hide)] = np.nan
    with pytest.raises(InputError, match="frames per bone"):
        estimate_height(pts)


def test_min_frames_counts_frames_with_both_ends():
    pts = walker(1.7, T=10)
    pts[:6, L_SH] = np.nan  # the trunk has both shoulders in 4 frames only
    with pytest.raises(InputError, match="trunk"):
        estimate_height(pts)
    assert estimate_height(pts, min_frames=4) == pytest.approx(1.7)


@pytest.mark.parametrize(
    "points, skeleton",
    [
        (np.zeros((5, 17, 2)), "coco17"),
        (np.zeros((5, 15, 3)), "coco17"),
        (np.zeros((5, 17, 3)), "nope"),
    ],
)
def test_bad_input_names_the_field(points, skeleton):
    with pytest.raises(InputError, match="points|skeleton"):
        estimate_height(points, skeleton)


def test_anny_bodies_of_known_height():
    """The mesh's top-to-sole extent is the body's true height; the estimate uses only its
    regressed COCO-17 keypoints, in the rest pose and in random poses. Within the +-5% the
    module docstring promises on average, and no body off by more than 8%."""
    cache = synth_ready("anny")
    from rmpl.synth.body import BodyModel, sample_phenotypes

    model = BodyModel(cache_dir=cache)
    n = 8
    phenotypes = sample_phenotypes(n, rng=5)
    rest = model(model.identity_pose(n), phenotypes)
    true = np.ptp(rest.vertices[..., 2], axis=1)
    posed = model(model.sample_poses(4 * n, rng=6), np.repeat(phenotypes, 4, 0))
    est = np.array(
        [estimate_height(posed.keypoints[4 * i : 4 * i + 4].astype(float), min_frames=4)
         for i in range(n)]
    )  # fmt: skip
    ratio = est / true
    assert abs(ratio.mean() - 1) < 0.05
    assert np.abs(ratio - 1).max() < 0.08
