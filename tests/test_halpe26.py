"""HALPE-26, the lifter's joint set beyond COCO-17: definitions, conversions, the training
sources that make it and the lifters that take any joint set in."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rmpl.errors import InputError
from rmpl.skeleton import (
    BLAZEPOSE33,
    BODY25,
    COCO17,
    HALPE26,
    convert,
    embed,
    embed_scores,
    to_model_joints,
)

EXTRA = HALPE26.joints[17:]


# ------------------------------------------------------------------ the joint set itself


def test_halpe26_starts_with_coco17_and_mirrors_onto_itself():
    assert HALPE26.joints[:17] == COCO17.joints
    assert EXTRA == ("head_top", "neck", "mid_hip", "left_big_toe", "right_big_toe",
                     "left_small_toe", "right_small_toe", "left_heel", "right_heel")  # fmt: skip
    perm = HALPE26.flip_permutation()
    assert sorted(perm) == list(range(26)) and (perm[perm] == np.arange(26)).all()
    for name in ("head_top", "neck", "mid_hip"):  # the midline maps onto itself
        assert perm[HALPE26.index(name)] == HALPE26.index(name)
    assert HALPE26.joints[perm[HALPE26.index("left_heel")]] == "right_heel"


def test_halpe26_to_shelf_uses_the_models_own_head_top_and_neck():
    x = np.arange(26 * 3, dtype=float).reshape(26, 3)
    y = convert(x, "halpe26", "shelf14")
    assert y[-1].tolist() == x[HALPE26.index("head_top")].tolist()
    assert y[-2].tolist() == x[HALPE26.index("neck")].tolist()
    assert y[0].tolist() == x[HALPE26.index("right_ankle")].tolist()
    assert convert(x, "halpe26", "coco17").tolist() == x[:17].tolist()


def test_embed_places_joints_by_name_and_leaves_the_rest_missing():
    kp = np.random.default_rng(0).normal(size=(4, 25, 2))
    sc = np.random.default_rng(1).uniform(0.1, 1, (4, 25))
    out, s = embed(kp, BODY25, HALPE26), embed_scores(sc, BODY25, HALPE26)
    assert out.shape == (4, 26, 2) and s.shape == (4, 26)
    for name in HALPE26.joints:
        i = HALPE26.index(name)
        if name == "head_top":  # BODY_25 has none
            assert np.isnan(out[:, i]).all() and (s[:, i] == 0).all()
        else:
            assert (out[:, i] == kp[:, BODY25.index(name)]).all()
            assert (s[:, i] == sc[:, BODY25.index(name)]).all()


def test_blazepose_foot_index_fills_the_big_toe_slot():
    kp = np.arange(33 * 2, dtype=float).reshape(33, 2)
    out = embed(kp, BLAZEPOSE33, HALPE26)
    big = HALPE26.index("left_big_toe")
    assert out[big].tolist() == kp[BLAZEPOSE33.index("left_foot_index")].tolist()
    assert out[HALPE26.index("left_heel")].tolist() == kp[BLAZEPOSE33.index("left_heel")].tolist()
    assert np.isnan(out[HALPE26.index("left_small_toe")]).all()


def test_to_model_joints_infers_coco17_and_refuses_unknown_counts():
    kp, sc = np.zeros((3, 2, 17, 2)), np.ones((3, 2, 17))
    k26, s26 = to_model_joints(kp, sc, "halpe26")
    assert k26.shape == (3, 2, 26, 2) and (s26[..., 17:] == 0).all()
    k, s = to_model_joints(k26, s26, "halpe26")  # its own set passes through
    assert k.shape == k26.shape
    with pytest.raises(ValueError, match="name their joint set"):
        to_model_joints(np.zeros((2, 20, 2)), np.ones((2, 20)), "halpe26")
    with pytest.raises(ValueError, match="has 25 joints"):
        to_model_joints(kp, sc, "halpe26", joints="body25")


# ------------------------------------------------------------------ parametric training pairs


def _poses26(n=64, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    base = np.zeros((26, 3))
    base[:, 2] = np.linspace(0.05, 1.7, 26)
    base[:, 0] = rng.uniform(-0.2, 0.2, 26)
    return base + rng.normal(0, 0.02, (n, 26, 3))


def test_pair_source_draws_one_detector_kind_per_sample():
    from rmpl.data.synthetic import PairSource, SamplerConfig
    from rmpl.synth.noise import INPUT_SETS

    only = {k: 0.0 for k in INPUT_SETS} | {"blazepose": 1.0}
    cfg = SamplerConfig(drop_rate=0.0, input_sets=tuple(only.items()))
    b = PairSource(_poses26(), cfg, seed=0).batch(32, 3)
    assert b.rays.shape == (32, 3, 26, 6) and b.target.shape == (32, 26, 3)
    given = b.scores > 0
    never = HALPE26.indices(["head_top", "neck", "mid_hip", "left_small_toe", "right_small_toe"])
    assert not given[..., never].any()
    assert given[..., HALPE26.indices(["left_heel", "right_big_toe"])].any()
    mixed = PairSource(_poses26(), SamplerConfig(drop_rate=0.0), seed=1).batch(256, 2)
    head = (mixed.scores[..., HALPE26.index("head_top")] > 0).any(1)
    assert 0 < head.mean() < 0.5  # HALPE-26 kinds only (0.2 of the samples), minus misses


def test_joint_sigmas_extend_coco17_values():
    from rmpl.synth.noise import NoiseConfig, joint_sigmas

    s = joint_sigmas(NoiseConfig().joint_sigma, 26)
    assert len(s) == 26 and (s[:17] == np.asarray(NoiseConfig().joint_sigma)).all()
    assert (s[17:] > 0).all()
    with pytest.raises(ValueError, match="20 joints"):
        joint_sigmas(NoiseConfig().joint_sigma, 20)


def test_coco17_sets_read_as_halpe26_have_missing_extras(tmp_path):
    from rmpl.data.mhp import ShardSource, load_mhp
    from tests.data.test_mhp import _fake_mhp

    _fake_mhp(tmp_path)
    d = load_mhp(tmp_path, joints="halpe26")
    assert d["joints3d"].shape[1:] == (26, 3) and np.isnan(d["joints3d"][:, 17:]).all()
    assert (d["scores"][..., 17:] == 0).all()
    assert np.array_equal(d["joints3d"][:, :17], load_mhp(tmp_path)["joints3d"])
    b = ShardSource(tmp_path, joints="halpe26", seed=0).batch(4, 2)
    assert b.target.shape == (4, 26, 3) and (b.scores[..., 17:] == 0).all()


# ------------------------------------------------------------------ training


def test_joint_loss_leaves_out_missing_targets():
    from rmpl.training.loop import joint_loss

    pred = torch.zeros(2, 26, 3)
    target = torch.full((2, 26, 3), float("nan"))
    target[:, :17] = 0.0
    target[:, :17, 0] = 0.5
    assert torch.isclose(joint_loss(pred, target), torch.tensor(0.5))
    assert torch.isfinite(joint_loss(pred.requires_grad_(), target))


def test_init_from_a_coco17_checkpoint(tmp_path):
    from rmpl.model.lifter import PRESETS, RMPL
    from rmpl.training.loop import INIT_FROM, init_from_checkpoint, save_checkpoint

    torch.manual_seed(0)
    small = RMPL(PRESETS["tiny"])
    save_checkpoint(small, tmp_path)
    big = RMPL(PRESETS["tiny"].with_(num_joints=26, skeleton="halpe26"))
    init_from_checkpoint(big, tmp_path)
    a, b = small.anatomy.detach()[0], big.anatomy.detach()[0]
    assert torch.equal(b[:17], a)
    for name, source in INIT_FROM.items():
        assert torch.equal(b[HALPE26.index(name)], a[COCO17.index(source)])
    assert torch.equal(big.head.weight, small.head.weight)
    # COCO-17 rays give the same COCO-17 answer (the new joints only add tokens the pose
    # transformer attends to, so the answers differ, but both are finite and shaped).
    rays = torch.randn(2, 3, 26, 6)
    rays[..., 3:] /= rays[..., 3:].norm(dim=-1, keepdim=True)
    scores = torch.rand(2, 3, 26)
    scores[..., 17:] = 0
    assert torch.isfinite(big(rays, scores)).all()


def test_training_refuses_poses_of_another_joint_set(tmp_path):
    from rmpl.training.loop import TrainConfig, train

    cfg = TrainConfig.from_dict(
        {"preset": "tiny", "steps": 1, "model": {"num_joints": 26, "skeleton": "halpe26"}}
    )
    poses17 = np.zeros((8, 17, 3))
    with pytest.raises(InputError, match="26 joints"):
        train(cfg, tmp_path, poses17, poses17)


# ------------------------------------------------------------------ lifting


@pytest.fixture(scope="module")
def lifter26(tmp_path_factory):
    from rmpl import Lifter
    from rmpl.model.lifter import PRESETS, RMPL
    from rmpl.training.loop import save_checkpoint

    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("halpe26")
    save_checkpoint(RMPL(PRESETS["tiny"].with_(num_joints=26, skeleton="halpe26")), path)
    return Lifter.from_pretrained(path, backend="torch")


def _rig_and_keypoints(J: int):
    from rmpl.geometry.camera import Camera, Rig, look_at, project

    K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    cams = [Camera(K, *look_at(np.array(e), np.array([0, 0, 1.0])), name=str(i))
            for i, e in enumerate([[3.0, 0, 1.5], [0, 3, 1.5], [-3, 0, 1.5]])]  # fmt: skip
    rig = Rig(tuple(cams))
    X = np.random.default_rng(0).normal([0, 0, 1.0], 0.3, (J, 3))
    kp = np.stack([project(X, c.K, c.R, c.t) for c in cams])[None]  # (1, V, J, 2)
    return rig, kp, np.ones(kp.shape[:-1])


def test_a_halpe26_lifter_takes_coco17_body25_and_its_own_joints(lifter26):
    assert lifter26.skeleton is HALPE26 and lifter26.num_joints == 26
    rig, kp26, sc26 = _rig_and_keypoints(26)
    full = lifter26.lift(kp26, sc26, rig)
    assert full.points.shape == (1, 26, 3) and (full.num_views == 3).all()
    coco = lifter26.lift(kp26[..., :17, :], sc26[..., :17], rig)
    assert coco.points.shape == (1, 26, 3) and np.isfinite(coco.points).all()
    assert (coco.num_views[..., 17:] == 0).all() and (coco.num_views[..., :17] == 3).all()
    # The same input as COCO-17 + missing extras, given as HALPE-26: the same answer.
    padded = embed(kp26[..., :17, :], COCO17, HALPE26)
    same = lifter26.lift(padded, embed_scores(sc26[..., :17], COCO17, HALPE26), rig)
    np.testing.assert_allclose(same.points, coco.points, atol=1e-6)
    with pytest.raises(InputError, match="keypoints"):
        lifter26.lift(np.zeros((1, 3, 20, 2)), np.ones((1, 3, 20)), rig)


def test_a_hidden_joint_starts_from_its_parent():
    from rmpl.model.lifter import parent_fallback
    from rmpl.skeleton import anchor_parents

    parents = torch.tensor(anchor_parents("halpe26"))
    X = torch.arange(26 * 3, dtype=torch.float32).reshape(1, 26, 3)
    valid = torch.ones(1, 26, dtype=torch.bool)
    names = ("left_small_toe", "left_big_toe", "left_ankle", "left_knee")
    small, big, ankle, knee = HALPE26.indices(names)
    valid[0, [small, big, ankle]] = False  # the chain climbs to the knee
    valid[0, HALPE26.index("nose")] = False  # no parent: keeps its own point
    out = parent_fallback(X, valid, parents)
    for j in (small, big, ankle):
        assert torch.equal(out[0, j], X[0, knee])
    assert torch.equal(out[0, HALPE26.index("nose")], X[0, HALPE26.index("nose")])
    keep = valid[0]
    assert torch.equal(out[0, keep], X[0, keep])


def test_anchor_parents_model_exports_and_keeps_the_default_model_unchanged():
    from rmpl.model.lifter import PRESETS, RMPL

    torch.manual_seed(0)
    plain = RMPL(PRESETS["tiny"].with_(num_joints=26, skeleton="halpe26")).eval()
    torch.manual_seed(0)
    tree = RMPL(PRESETS["tiny"].with_(num_joints=26, skeleton="halpe26", anchor_parents=True))
    tree.eval()
    from rmpl.geometry.rays import rays_from_keypoints

    rig, kp, _ = _rig_and_keypoints(26)  # a consistent pose: every joint's rays meet
    rays = torch.from_numpy(rays_from_keypoints(kp, rig).astype(np.float32))
    scores = torch.rand(1, 3, 26) * 0.5 + 0.5
    with torch.no_grad():
        assert torch.equal(plain(rays, scores), tree(rays, scores))  # every joint seen
        scores[..., 17:] = 0
        assert not torch.equal(plain(rays, scores), tree(rays, scores))
    with pytest.raises(ValueError, match="num_joints"):
        RMPL(PRESETS["tiny"].with_(num_joints=17, skeleton="halpe26", anchor_parents=True))


# ------------------------------------------------------------------ motion on anny bodies


@pytest.fixture(scope="module")
def one_clip(tmp_path_factory):
    """One short CMU clip (subject 02, trial 01) copied into its own folder."""
    import shutil

    from tests.conftest import shared_data_root, synth_ready

    root = shared_data_root()
    src = None if root is None else root / "cmu_mocap/asfamc/data/CMU/asfamc/subjects/02"
    if src is None or not (src / "02_01.amc").is_file():
        pytest.skip("CMU subject 02 not found in ../shared/data/cmu_mocap")
    cache = synth_ready("anny")
    out = tmp_path_factory.mktemp("clip") / "02"
    out.mkdir()
    for name in ("02.asf", "02_01.amc"):
        shutil.copy(src / name, out / name)
    return out.parent, cache


def test_motion_posed_on_anny_follows_the_mocap(one_clip):
    from rmpl.data.sequences import SequenceBank, anny_sequence_bank
    from rmpl.synth.body import BodyModel
    from rmpl.synth.retarget import anny_pose_set, build_pose_bank, limb_angles

    root, cache = one_clip
    body = BodyModel(cache_dir=cache, joints="halpe26")
    seq = anny_sequence_bank(root, body, fps=10)
    mocap = SequenceBank.from_motion_dir(root, fps=10)
    assert seq.poses.shape == (len(mocap.poses), 26, 3)
    assert np.array_equal(seq.length, mocap.length)
    # The limbs point where the mocap's do; the segment stands on the floor.
    angles = limb_angles(mocap.poses.astype(float), seq.poses[:, :17].astype(float))
    assert np.median(angles) < 8
    assert 0 <= seq.poses[..., 2].min() < 0.1
    # One body per segment: a thigh keeps its length.
    first = seq.poses[seq.start[0] : seq.start[0] + seq.length[0]]
    thigh = np.linalg.norm(first[:, 11] - first[:, 13], axis=-1)
    assert thigh.std() < 0.01 * thigh.mean()
    # The single-pose bank: HALPE-26 per pose, heels near their ankles.
    poses = anny_pose_set(build_pose_bank(root, fps=2), body)
    assert poses.poses.shape[1:] == (26, 3) and len(poses) > 0
    heel = np.linalg.norm(poses.poses[:, 24] - poses.poses[:, 15], axis=-1)
    assert (heel > 0.02).all() and (heel < 0.15).all()


def test_rmpl_poses_sequences_on_anny_writes_halpe26(one_clip, tmp_path, monkeypatch):
    from rmpl.cli import main
    from rmpl.data.sequences import SequenceBank

    root, cache = one_clip
    monkeypatch.setenv("ANNY_CACHE_DIR", str(cache))
    out = tmp_path / "seq.npz"
    assert main(["poses", str(root), "--sequences", "--body", "anny", "--fps", "5",
                 "--out", str(out)]) == 0  # fmt: skip
    assert SequenceBank.load(out).poses.shape[1:] == (26, 3)


@pytest.mark.parametrize(
    "sets", [{"coco17": -1.0, "halpe26": 2.0}, {"openpose": 1.0}, {"coco17": 0.0}]
)
def test_detector_kinds_are_checked_where_they_are_given(sets):
    from rmpl.data.sequences import SequenceBank, SequenceSource
    from rmpl.data.synthetic import SamplerConfig

    with pytest.raises(ValueError, match="input_sets"):
        SamplerConfig(input_sets=sets)
    bank = SequenceBank(np.zeros((10, 26, 3), np.float32), np.array([0]), np.array([10]),
                        np.array(["01"]), 30.0)  # fmt: skip
    with pytest.raises(ValueError, match="input_sets"):
        SequenceSource(bank, input_sets=tuple(sets.items()))


def test_the_shipped_halpe26_model_runs_alike_in_onnx_with_hidden_extras():
    pytest.importorskip("onnxruntime")
    from rmpl import Lifter
    from rmpl.geometry.rays import rays_from_keypoints
    from rmpl.model.export import OnnxLifter

    lifter = Lifter.from_pretrained("halpe26", backend="torch")
    rig, kp, _ = _rig_and_keypoints(26)
    rays = rays_from_keypoints(kp, rig).astype(np.float32)
    scores = np.ones(kp.shape[:-1], np.float32)
    scores[..., 17:] = 0  # a COCO-17 detector: the extras start from their parents
    with torch.no_grad():
        ref = lifter.model(torch.from_numpy(rays), torch.from_numpy(scores)).numpy()
    np.testing.assert_allclose(OnnxLifter(lifter.model)(rays, scores), ref, atol=1e-4)
    assert lifter.model.config.anchor_parents and np.isfinite(ref).all()


def test_the_run_refuses_2d_in_a_set_it_cannot_index():
    from rmpl.pipeline.runner import input_skeleton

    assert input_skeleton(17) == "coco17" and input_skeleton(26, "halpe26") == "halpe26"
    with pytest.raises(InputError, match="coco17 or halpe26"):
        input_skeleton(25, "body25")
    with pytest.raises(InputError, match="17 \\(COCO-17\\) or 26"):
        input_skeleton(20)
