"""Retargeting CMU motion onto anny: after retargeting, anny's regressed COCO-17 limbs point
where the mocap's limbs point. Needs anny (its cache is built on first use, see
tests.conftest.synth_ready) and the CMU
data of ../shared/data."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.synth.retarget import implausible, limb_angles, min_rotation
from tests.conftest import synth_ready

# Stated tolerance: over sampled frames, the median angle between anny's regressed limb
# directions (upper arms, forearms, thighs, shanks) and the mocap's is below 6 degrees and
# the 95th percentile below 15 degrees. The residual is the different joint definitions
# (COCO hip/shoulder on the body surface vs. mocap joint centres), not the rotations.
MEDIAN_DEG, P95_DEG = 6.0, 15.0


def test_min_rotation_aligns_directions():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((200, 3))
    b = rng.standard_normal((200, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    b[0] = -a[0]  # opposite directions
    R = min_rotation(a, b)
    assert np.allclose(np.einsum("nij,nj->ni", R, a), b, atol=1e-9)
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(R), 1.0)


def test_implausible_flags_crossed_legs():
    k = np.zeros((2, 17, 3))
    for side, x in ((0, 0.1), (1, -0.1)):  # left joints at +x, right at -x
        k[:, 11 + side] = [x, 0, 0.9]
        k[:, 13 + side] = [x, 0, 0.5]
        k[:, 15 + side] = [x, 0, 0.1]
        k[:, 7 + side] = [2 * x, 0, 1.2]
        k[:, 9 + side] = [3 * x, 0, 1.0]
    k[1, 14] = [0.1, 0.0, 0.5]  # the right knee inside the left thigh
    assert implausible(k).tolist() == [False, True]


def _body_model():
    cache = synth_ready("anny")
    from rmpl.synth.body import BodyModel

    return BodyModel(cache_dir=cache)


@pytest.mark.shared
@pytest.mark.parametrize("subject", ["03", "16", "12"])  # ASF/AMC, CMU-named BVH, Daz BVH
def test_retargeted_limbs_follow_the_mocap(shared_data, subject):
    from rmpl.synth.body import sample_phenotypes
    from rmpl.synth.motion import mirror
    from rmpl.synth.retarget import build_pose_bank, mirror_pose, retarget

    root = shared_data / "cmu_mocap"
    if not root.is_dir():
        pytest.skip(f"{root} not found")
    model = _body_model()
    bank = build_pose_bank(root, subjects=[subject])
    rng = np.random.default_rng(0)
    idx = rng.choice(len(bank), min(24, len(bank)), replace=False)
    phen = sample_phenotypes(len(idx), rng)
    pose = retarget(model, bank, idx, phen)
    bodies = model(pose, phen)
    angles = limb_angles(bodies.keypoints, bank.joints[idx])
    assert np.median(angles) < MEDIAN_DEG, np.median(angles)
    assert np.percentile(angles, 95) < P95_DEG, np.percentile(angles, 95)
    # Without retargeting (rest pose) the limbs are far off: the test can fail.
    rest = model(model.identity_pose(len(idx)), phen)
    assert np.median(limb_angles(rest.keypoints, bank.joints[idx])) > MEDIAN_DEG
    # Mirrored deltas give the mirrored body.
    mirrored = model(mirror_pose(pose, model.bone_names), phen)
    assert limb_angles(mirrored.keypoints, mirror(bodies.keypoints)).max() < 1.0
