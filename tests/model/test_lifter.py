import numpy as np
import pytest
import torch

from rmpl.model.lifter import (
    PRESETS,
    RMPL,
    MLPLifter,
    RMPLConfig,
    anchors_from_rays,
    build_model,
    camera_features,
)
from rmpl.training.loop import load_checkpoint, save_checkpoint


def scene(B=4, V=4, seed=0):
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(B, 17, 3, generator=g) * torch.tensor([0.6, 0.6, 1.7])
    ang = torch.rand(B, V, generator=g) * 6.28
    C = torch.stack([4 * ang.cos(), 4 * ang.sin(), 1 + torch.rand(B, V, generator=g)], -1)
    d = X[:, None] - C[:, :, None]
    d = d / d.norm(dim=-1, keepdim=True)
    rays = torch.cat([C[:, :, None].expand_as(d), d], -1)
    scores = 0.5 + 0.5 * torch.rand(B, V, 17, generator=g)
    return rays, scores, X


def tiny(**kw):
    torch.manual_seed(0)
    return RMPL(PRESETS["tiny"].with_(**kw)).eval()


@pytest.mark.parametrize("V", range(1, 11))
def test_shapes_any_number_of_views(V):
    rays, scores, _ = scene(2, V)
    out = tiny()(rays, scores)
    assert out.shape == (2, 17, 3)
    assert torch.isfinite(out).all()


def test_masked_view_changes_nothing():
    model = tiny(geometric=True)
    # Randomise the zero-initialised head so the test sees the network, not the anchor.
    torch.nn.init.normal_(model.head.weight, std=0.1)
    rays, scores, _ = scene(3, 3)
    ref = model(rays, scores)
    garbage = torch.cat([rays, torch.randn(3, 1, 17, 6) * 10], 1)
    more = model(garbage, torch.cat([scores, torch.zeros(3, 1, 17)], 1))
    assert torch.allclose(ref, more, atol=1e-5)
    nan_rays = garbage.clone()
    nan_rays[:, -1] = float("nan")
    assert torch.allclose(
        ref, model(nan_rays, torch.cat([scores, torch.ones(3, 1, 17)], 1)), atol=1e-5
    )


@pytest.mark.parametrize("geometric", [True, False])
def test_permutation_invariance(geometric):
    model = tiny(geometric=geometric)
    torch.nn.init.normal_(model.head.weight, std=0.1)
    rays, scores, _ = scene(2, 5)
    perm = torch.tensor([3, 0, 4, 1, 2])
    assert torch.allclose(model(rays, scores), model(rays[:, perm], scores[:, perm]), atol=1e-5)


def test_geometric_model_starts_at_triangulation():
    rays, scores, X = scene(4, 4)
    out = tiny(geometric=True)(rays, scores)
    assert (out - X).norm(dim=-1).max() < 1e-4


def test_anchor_single_view_is_in_front_of_camera():
    rays, scores, X = scene(2, 1)
    pts, valid, P = anchors_from_rays(rays, scores)
    assert not valid.any()
    C = rays[:, 0, 0, :3]
    dist = (P - C).norm(dim=-1)
    true = (X.mean(1) - C).norm(dim=-1)
    assert ((dist / true) > 0.3).all() and ((dist / true) < 3).all()


def test_overfit_one_batch():
    torch.manual_seed(0)
    model = RMPL(PRESETS["tiny"].with_(geometric=False)).train()
    rays, scores, X = scene(8, 3)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    first = None
    for _ in range(300):
        loss = (model(rays, scores) - X).norm(dim=-1).mean()
        first = first or loss.item()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.2 * first


def test_wrong_joint_count_is_clear():
    with pytest.raises(ValueError, match="17 joints"):
        tiny()(torch.zeros(1, 2, 15, 6), torch.ones(1, 2, 15))


def test_checkpoint_round_trip(tmp_path):
    model = tiny()
    torch.nn.init.normal_(model.head.weight, std=0.1)
    save_checkpoint(model, tmp_path / "ck", {"note": "x"})
    loaded, meta = load_checkpoint(tmp_path / "ck")
    assert meta["note"] == "x" and meta["skeleton"] == "coco17"
    rays, scores, _ = scene(2, 3)
    assert torch.equal(model(rays, scores), loaded(rays, scores))
    assert not list((tmp_path / "ck").glob("*.part*"))


def test_config_rejects_unknown_keys():
    with pytest.raises(ValueError, match="unknown RMPLConfig keys"):
        RMPLConfig.from_dict({"dim": 64, "width": 3})


def test_paper_preset_size():
    n = RMPL(PRESETS["paper"]).num_parameters
    assert 12.0e6 < n < 13.5e6  # the thesis reports 12.7M
    del n
    np.testing.assert_equal(PRESETS["paper"].dim, 256)


# Ablation variants (thesis 6.4, 6.6): pixel inputs and the fully connected baseline.


def pixel_inputs(rays, seed=0):
    B, V, J, _ = rays.shape
    g = torch.Generator().manual_seed(seed)
    kp = torch.rand(B, V, J, 2, generator=g) * 1000
    K = torch.tensor([[1000.0, 0, 500], [0, 1000, 500], [0, 0, 1]]).expand(B, V, 3, 3)
    cams = camera_features(K, torch.eye(3).expand(B, V, 3, 3), torch.rand(B, V, 3, generator=g))
    return kp, cams


@pytest.mark.parametrize("inputs", ["pixels", "pixels+calib"])
def test_pixel_models_use_their_inputs(inputs):
    torch.manual_seed(0)
    model = build_model(PRESETS["tiny"].with_(inputs=inputs, recenter=False, geometric=False))
    rays, scores, _ = scene(2, 3)
    kp, cams = pixel_inputs(rays)
    out = model.eval()(rays, scores, kp, cams)
    assert out.shape == (2, 17, 3)
    assert not torch.allclose(out, model(rays, scores, kp + 50, cams))
    # The rays themselves are not an input of a pixel model.
    torch.testing.assert_close(out, model(rays.flip(-1), scores, kp, cams))
    with pytest.raises(ValueError, match="needs keypoints"):
        model(rays, scores)


def test_pixel_inputs_cannot_be_recentered():
    with pytest.raises(ValueError, match="recenter=false"):
        PRESETS["tiny"].with_(inputs="pixels")
    with pytest.raises(ValueError, match="inputs must be one of"):
        PRESETS["tiny"].with_(inputs="depth", recenter=False, geometric=False)


def test_mlp_baseline_shapes_masking_and_limit():
    torch.manual_seed(0)
    model = build_model(PRESETS["tiny"].with_(architecture="mlp", geometric=False, max_views=4))
    assert isinstance(model, MLPLifter)
    torch.nn.init.normal_(model.head[1].weight, std=0.1)
    rays, scores, _ = scene(2, 3)
    out = model.eval()(rays, scores)
    assert out.shape == (2, 17, 3) and torch.isfinite(out).all()
    # A fourth, fully masked view is the same as zero padding.
    rays4 = torch.cat([rays, torch.randn(2, 1, 17, 6)], 1)
    scores4 = torch.cat([scores, torch.zeros(2, 1, 17)], 1)
    torch.testing.assert_close(model(rays4, scores4), out)
    with pytest.raises(ValueError, match="at most 4 views"):
        model(torch.cat([rays4, rays4], 1), torch.cat([scores4, scores4], 1))


def test_mlp_checkpoint_round_trip(tmp_path):
    model = build_model(PRESETS["tiny"].with_(architecture="mlp", geometric=False))
    torch.nn.init.normal_(model.head[1].weight, std=0.1)
    save_checkpoint(model, tmp_path / "ck")
    loaded, _ = load_checkpoint(tmp_path / "ck")
    assert isinstance(loaded, MLPLifter)
    rays, scores, _ = scene(2, 3)
    assert torch.equal(model.eval()(rays, scores), loaded(rays, scores))


def _with_outlier_ray(rays, X, b, j, shift):
    """Rays with view 0 of (sample b, joint j) re-aimed at a point ``shift`` metres away."""
    rays = rays.clone()
    C = rays[b, 0, j, :3]
    d = X[b, j] + torch.tensor(shift) - C
    rays[b, 0, j, 3:] = d / d.norm()
    return rays


def test_robust_anchor_ignores_an_outlying_view():
    rays, scores, X = scene(2, 4)
    bad = _with_outlier_ray(rays, X, 0, 5, [0.0, 0.0, 0.5])  # vertical: far from every ray
    plain = anchors_from_rays(bad, scores)[0]
    robust = anchors_from_rays(bad, scores, robust=3)[0]
    assert (plain[0, 5] - X[0, 5]).norm() > 0.05  # least squares is pulled off
    assert (robust[0, 5] - X[0, 5]).norm() < 0.2 * (plain[0, 5] - X[0, 5]).norm()
    # Exact rays and two-view joints are unchanged by the reweighting.
    assert torch.allclose(anchors_from_rays(rays, scores, robust=3)[0], X, atol=1e-4)
    r2, s2, _ = scene(2, 2)
    assert torch.allclose(anchors_from_rays(r2, s2, robust=3)[0], anchors_from_rays(r2, s2)[0])


def test_robust_anchor_model_starts_at_robust_triangulation():
    rays, scores, X = scene(2, 4)
    bad = _with_outlier_ray(rays, X, 1, 9, [0.0, 0.4, 0.2])
    out = tiny(robust_anchor=3)(bad, scores)
    plain = tiny()(bad, scores)
    assert (out[1, 9] - X[1, 9]).norm() < 0.2 * (plain[1, 9] - X[1, 9]).norm()
    with pytest.raises(ValueError, match="robust_anchor"):
        RMPLConfig(robust_anchor=-1)
    for bad in (1.5, True):
        with pytest.raises(ValueError, match="robust_anchor"):
            RMPLConfig(robust_anchor=bad)


@pytest.mark.parametrize("name", ["default", "occlusion", "halpe26", "floor26", "scenes26"])
def test_shipped_models_load_and_lift(name):
    """Every shipped model loads by name and lifts exact 2D from 3 views close to the truth."""
    from rmpl.geometry.camera import Camera, Rig, look_at
    from rmpl.inference import PRETRAINED, Lifter

    assert name in PRETRAINED
    lifter = Lifter.from_pretrained(name, backend="torch")
    assert lifter.model.config.robust_anchor > 0
    rng = np.random.default_rng(0)
    K = np.array([[900.0, 0, 480], [0, 900, 360], [0, 0, 1]])
    cams = []
    for v in range(3):
        a = 2 * np.pi * v / 3
        R, t = look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 2.0]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(960, 720), name=f"c{v}"))
    rig = Rig(tuple(cams))
    from tests.cli.test_evaluate import standing_poses

    X = standing_poses(8, rng).astype(float)
    out = lifter.lift(rig.project(X), np.full((8, 3, 17), 0.9), rig).points[:, :17]
    assert np.isfinite(out).all()
    assert np.linalg.norm(out - X, axis=-1).mean() < 0.1
    if lifter.reads_floor:  # the floor given (standing_poses stand on z = 0)
        from rmpl.geometry.floor import Floor

        floor = Floor((0.0, 0.0, 1.0), 0.0)
        out = lifter.lift(rig.project(X), np.full((8, 3, 17), 0.9), rig, floor=floor).points
        assert np.linalg.norm(out[:, :17] - X, axis=-1).mean() < 0.1


def test_model_help_names_every_shipped_model():
    """The --model help (built without importing torch) lists every shipped model."""
    from rmpl.inference import PRETRAINED
    from rmpl.inference_temporal import PRETRAINED_TEMPORAL
    from rmpl.models import MODEL_HELP

    assert all(name in MODEL_HELP for name in [*PRETRAINED, *PRETRAINED_TEMPORAL])
