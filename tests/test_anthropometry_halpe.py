"""Height with HALPE-26's head top and feet (rmpl.anthropometry): the crown and the ankle's
height above the sole are measured instead of taken from the proportions; known values on a
body built from the proportions, and anny bodies of known height."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.anthropometry import CHAIN_FRACTION, EXTRA_FRACTIONS, bone_lengths, estimate_height
from rmpl.skeleton import HALPE26
from tests.conftest import synth_ready

J = {name: i for i, name in enumerate(HALPE26.joints)}


def standing(H: float, T: int = 6, crown: float | None = None, ankle: float | None = None):
    """A HALPE-26 body standing upright at the proportions' heights (z up), (T, 26, 3); the
    crown (shoulder to vertex) and ankle height may differ from the proportions."""
    crown = (1 - 0.818) * H if crown is None else crown
    ankle = 0.039 * H if ankle is None else ankle
    x = np.zeros((26, 3))
    for side, s in (("left", 1), ("right", -1)):
        x[J[f"{side}_hip"]] = [0.1 * s, 0, 0.530 * H]
        x[J[f"{side}_knee"]] = [0.1 * s, 0, 0.285 * H]
        x[J[f"{side}_ankle"]] = [0.1 * s, 0, ankle]
        x[J[f"{side}_shoulder"]] = [0.18 * s, 0, 0.818 * H]
        x[J[f"{side}_heel"]] = [0.1 * s, 0.05, 0.0]  # the sole: z = 0, tilted toes on it
        x[J[f"{side}_big_toe"]] = [0.08 * s, -0.15, 0.0]
        x[J[f"{side}_small_toe"]] = [0.14 * s, -0.13, 0.0]
    x[J["head_top"]] = [0.0, 0.02, 0.818 * H + np.sqrt(crown**2 - 0.02**2)]
    return np.repeat(x[None], T, 0)


def test_a_body_at_the_proportions_gives_its_height():
    H = 1.74
    assert estimate_height(standing(H), "halpe26") == pytest.approx(H, rel=1e-9)
    lengths = bone_lengths(standing(H), "halpe26")
    assert lengths["crown"][0] == pytest.approx((1 - 0.818) * H)
    assert lengths["left_ankle_height"][0] == pytest.approx(0.039 * H)


def test_the_measured_spans_replace_the_proportions():
    """A long head and low ankles: the estimate follows what is measured, and sums to the
    measured height (all spans measured cover the whole height): shoulder height 0.818 H
    (the shank now ends at the lower ankle) plus the crown."""
    H, crown, ankle = 1.70, 0.36, 0.05
    est = estimate_height(standing(H, crown=crown, ankle=ankle), "halpe26")
    assert est == pytest.approx(0.818 * H + crown, rel=1e-9)
    assert CHAIN_FRACTION + sum(EXTRA_FRACTIONS.values()) == pytest.approx(1.0)


def test_unseen_head_top_or_feet_fall_back_to_the_proportions():
    H = 1.70
    x = standing(H, crown=0.40, ankle=0.02)
    no_head = x.copy()
    no_head[:, J["head_top"]] = np.nan
    assert estimate_height(no_head, "halpe26") == pytest.approx(  # 0.818 H measured
        (0.818 * H) / (CHAIN_FRACTION + 0.039), rel=1e-9
    )
    no_feet = x.copy()
    no_feet[:, [J["left_heel"], J["right_heel"]]] = np.nan
    assert estimate_height(no_feet, "halpe26") == pytest.approx(  # shank to the low ankle
        (0.818 * H - 0.02 + 0.40) / (CHAIN_FRACTION + 1 - 0.818), rel=1e-9
    )
    coco = estimate_height(x[:, :17], "coco17")
    both = x.copy()
    both[:, [J["head_top"], J["left_heel"], J["right_heel"]]] = np.nan
    assert estimate_height(both, "halpe26") == pytest.approx(coco, rel=1e-12)
    assert coco == pytest.approx((0.818 * H - 0.02) / CHAIN_FRACTION, rel=1e-9)


def test_the_ankle_height_does_not_depend_on_the_foot_pose():
    """A rigid foot turned (plantar flexion about the ankle): the ankle's distance from the
    sole plane, so the height, is unchanged."""
    H = 1.80
    x = standing(H)
    a = np.radians(30)
    R = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    for side in ("left", "right"):
        ankle = x[:, J[f"{side}_ankle"]]
        for part in ("heel", "big_toe", "small_toe"):
            k = J[f"{side}_{part}"]
            x[:, k] = ankle + (x[:, k] - ankle) @ R.T
    assert estimate_height(x, "halpe26") == pytest.approx(H, rel=1e-9)


@pytest.mark.parametrize("posed", [False, True])
def test_anny_bodies_halpe26_beside_coco17(posed):
    """anny bodies (true height: the rest mesh's top-to-sole extent): with the head top and
    the feet the estimate is within 2% (rest pose) or the promised 5% (random poses, where
    the skin-regressed keypoints move against the bones) for every body, and its error is
    no larger than COCO-17's on average."""
    cache = synth_ready("anny")
    from rmpl.synth.body import BodyModel, sample_phenotypes

    model = BodyModel(cache_dir=cache, joints="halpe26")
    n = 12
    phenotypes = sample_phenotypes(n, rng=5)
    rest = model(model.identity_pose(n), phenotypes)
    true = np.ptp(rest.vertices[..., 2], axis=1)
    bodies = model(model.sample_poses(4 * n, rng=6), np.repeat(phenotypes, 4, 0)) if posed else rest
    k = 4 if posed else 1
    kp = bodies.keypoints.astype(float).reshape(n, k, 26, 3)
    kp = np.repeat(kp, 4 // k, axis=1)  # four frames per body
    halpe = np.array([estimate_height(p, "halpe26", min_frames=4) for p in kp])
    coco = np.array([estimate_height(p[:, :17], "coco17", min_frames=4) for p in kp])
    err_h, err_c = np.abs(halpe / true - 1), np.abs(coco / true - 1)
    mean, worst = (
        100 * np.array([err_h.mean(), err_c.mean()]),
        100 * np.array([err_h.max(), err_c.max()]),
    )
    print(f"posed={posed}: |error| mean HALPE-26 {mean[0]:.1f}%, COCO-17 {mean[1]:.1f}%; "
          f"max {worst[0]:.1f}% / {worst[1]:.1f}%")  # fmt: skip
    assert err_h.max() < (0.05 if posed else 0.02)
    assert err_h.mean() <= err_c.mean()
